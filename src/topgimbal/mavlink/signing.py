"""Moved to `topgimbal.links.signing` (issue 44: the links are the layer under the bridge); the old
import path stays an alias of the new module, so code that imports it keeps working."""

import sys

from ..links import signing as _moved

sys.modules[__name__] = _moved
