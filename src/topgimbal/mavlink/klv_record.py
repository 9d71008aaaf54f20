"""Moved to `topgimbal.outputs.klv_record` (issue 44: outputs that are not MAVLink left mavlink/); the old
import path stays an alias of the new module, so code that imports it keeps working."""

import sys

from ..outputs import klv_record as _moved

sys.modules[__name__] = _moved
