"""MAVLink camera definitions (the XML a ground station reads for a camera's settings): generated
from the catalog (definition.py, pure), written and checked under contrib/camera-definitions/
(files.py, `make docs`) and served read-only over HTTP for `cam_definition_uri` (http.py).

Nothing here needs pymavlink or the bridge: the bridge (topgimbal.mavlink) serves these files, the
docs tool writes them (tests/test_architecture.py)."""
