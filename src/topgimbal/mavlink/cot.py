"""Moved to `topgimbal.outputs.cot` (issue 44: outputs that are not MAVLink left mavlink/); the old
import path stays an alias of the new module, so code that imports it keeps working."""

import sys

from ..outputs import cot as _moved

sys.modules[__name__] = _moved
