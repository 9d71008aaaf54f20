"""What the bridge learns from and asks of the autopilots on its MAVLink network, below the bridge
core (issue 44): each vehicle's position, attitude and time (vehicle.py), where each of the camera's
feeds comes from (feed_sources.py), how fast the autopilot sends on this link (stream_rates.py), its
reboots (reboots.py), and asking it for the messages the photos need (streams.py).

It reads pymavlink's messages and sends through a `streams.Sender` it is given; it imports neither
the bridge nor the camera (tests/test_architecture.py)."""
