"""LCM message types of the robot: its status, its motor commands and the poses it follows live
(docs/lcm.md).

The ``.lcm`` files beside this one are the definitions; ``lcmt_*.py`` are generated from them by
``lcm-gen --python --python-no-init --ppath . stewart_drake/lcmtypes/*.lcm`` run at the
repository's top (lcm 1.5.3, the version the ``lcm`` extra pins) and committed: never edit them by
hand (``tests/test_lcm_types.py`` regenerates them and compares byte for byte). They import only
the standard library, so reading or writing a message needs neither Drake nor the ``lcm`` package.
"""

from .lcmt_stewart_command import lcmt_stewart_command
from .lcmt_stewart_pose_sample import lcmt_stewart_pose_sample
from .lcmt_stewart_status import lcmt_stewart_status

__all__ = ["lcmt_stewart_command", "lcmt_stewart_pose_sample", "lcmt_stewart_status"]
