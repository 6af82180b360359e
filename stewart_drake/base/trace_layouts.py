"""The layouts a trace file may have, by name (a command's ``--format``, a scenario's
``reference.format``): the ones read by their header line ("csv"; "auto" first looks for one), a
Varian RPM export ("vxp", known by its ``[Header]``), and the formats without a header, whose
columns and units are written here (:data:`HEADERLESS_FORMATS`). Only names and text: the
commands' parsers read it without numpy; :mod:`stewart_drake.references.trace_files` reads the
files.
"""

#: The columns of the 6-D motion phantom format (Image-X Institute's IntERAct: text without a
#: header, one sample per line, numbers separated by spaces, 5 Hz in its library): time, the
#: target's translation in the patient's axes, and its rotation about them.
PHANTOM_COLUMNS = "t [s], LR [mm], SI [mm], AP [mm], rot_LR [deg], rot_SI [deg], rot_AP [deg]"
#: The columns of a phantom's external surrogate file (2 columns without a header: time and the
#: marker's displacement): the displacement goes to the patient's SI unless mapped elsewhere.
SURROGATE_COLUMNS = "t [s], surrogate [mm]"

#: The formats without a header line: {name: its columns and units, as ``--columns`` writes
#: them}. A file of one is read by these columns; "auto" reads a file without a header by its
#: width, the first format of that width here. The one place to add such a format: its name
#: reaches every command's ``--format`` and a scenario's ``format`` (:func:`trace_formats`).
HEADERLESS_FORMATS = {"phantom": PHANTOM_COLUMNS, "surrogate": SURROGATE_COLUMNS}


def trace_formats() -> tuple[str, ...]:
    """Every layout's name, in the order ``--format`` lists them: "auto", "csv", each of
    :data:`HEADERLESS_FORMATS`, "vxp"."""
    return ("auto", "csv", *HEADERLESS_FORMATS, "vxp")


def headerless_format_of_width(width: int) -> str | None:
    """The first of :data:`HEADERLESS_FORMATS` with ``width`` columns (None: none has)."""
    for name, columns in HEADERLESS_FORMATS.items():
        if len(columns.split(",")) == width:
            return name
    return None


__all__ = [
    "HEADERLESS_FORMATS",
    "PHANTOM_COLUMNS",
    "SURROGATE_COLUMNS",
    "headerless_format_of_width",
    "trace_formats",
]
