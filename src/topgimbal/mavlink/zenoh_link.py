"""Moved to `topgimbal.links.zenoh_link` (issue 44: the links are the layer under the bridge); the old
import path stays an alias of the new module, so code that imports it keeps working."""

import sys

from ..links import zenoh_link as _moved

sys.modules[__name__] = _moved
