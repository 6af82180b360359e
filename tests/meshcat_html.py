"""Read back the scene of a Meshcat static HTML: the base64 msgpack commands it replays on load.

A minimal msgpack decoder (the subset Drake's Meshcat writes), so the tests need no msgpack
package and check the file the way the browser will read it.
"""

import base64
import re
import struct

_FIXED = {
    0xCA: ">f",
    0xCB: ">d",
    0xCC: ">B",
    0xCD: ">H",
    0xCE: ">I",
    0xCF: ">Q",
    0xD0: ">b",
    0xD1: ">h",
    0xD2: ">i",
    0xD3: ">q",
}
# first byte -> (bytes of the length field, kind)
_SIZED = {
    0xC4: (1, "bin"),
    0xC5: (2, "bin"),
    0xC6: (4, "bin"),
    0xD9: (1, "str"),
    0xDA: (2, "str"),
    0xDB: (4, "str"),
    0xDC: (2, "array"),
    0xDD: (4, "array"),
    0xDE: (2, "map"),
    0xDF: (4, "map"),
    0xC7: (1, "ext"),
    0xC8: (2, "ext"),
    0xC9: (4, "ext"),
}


def unpackb(data: bytes):
    value, end = _decode(data, 0)
    assert end == len(data), f"{len(data) - end} trailing bytes"
    return value


def _decode(b: bytes, i: int):
    c = b[i]
    i += 1
    if c <= 0x7F:
        return c, i
    if c >= 0xE0:
        return c - 0x100, i
    if c <= 0x8F:
        return _container(b, i, c & 0x0F, "map")
    if c <= 0x9F:
        return _container(b, i, c & 0x0F, "array")
    if c <= 0xBF:
        n = c & 0x1F
        return b[i : i + n].decode(), i + n
    if c == 0xC0:
        return None, i
    if c in (0xC2, 0xC3):
        return c == 0xC3, i
    if c in _FIXED:
        n = struct.calcsize(_FIXED[c])
        return struct.unpack(_FIXED[c], b[i : i + n])[0], i + n
    if 0xD4 <= c <= 0xD8:  # fixext 1..16
        n = 1 << (c - 0xD4)
        return ("ext", b[i], b[i + 1 : i + 1 + n]), i + 1 + n
    width, kind = _SIZED[c]
    n = int.from_bytes(b[i : i + width], "big")
    i += width
    if kind == "bin":
        return b[i : i + n], i + n
    if kind == "str":
        return b[i : i + n].decode(), i + n
    if kind == "ext":
        return ("ext", b[i], b[i + 1 : i + 1 + n]), i + 1 + n
    return _container(b, i, n, kind)


def _container(b: bytes, i: int, n: int, kind: str):
    items = []
    for _ in range(2 * n if kind == "map" else n):
        value, i = _decode(b, i)
        items.append(value)
    if kind == "map":
        return dict(zip(items[::2], items[1::2])), i
    return items, i


def read_meshcat_commands(html: str) -> list:
    """The commands (dicts with "type", "path", ...) a static Meshcat HTML feeds its viewer."""
    payloads = re.findall(r"data:application/octet-binary;base64,([A-Za-z0-9+/=]+)", html)
    return [unpackb(base64.b64decode(p)) for p in payloads]
