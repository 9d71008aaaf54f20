"""MAVLink links: bytes over UDP, TCP, serial, the in-process `memory:NAME` and Zenoh (BlueOS's
JSON shape), MAVLink 2 signing, and the one import of pymavlink (`mav.py`).

The layer under the bridge (`topgimbal.mavlink`), as a transport is under a client: a link moves
bytes to and from peers and bounds what it holds (peers, queued bytes); it knows no gimbal, camera
or command. The bridge's node parses and dispatches what the links carry (mavlink/node.py).
Nothing here imports the bridge (tests/test_architecture.py)."""
