"""Outputs that are not MAVLink: Cursor-on-Target for TAK (cot.py over cot_stream.py), MISB ST 0601
KLV (klv.py) and its recorder (klv_record.py), the RTP video out's options (rtp_out.py). Each is
fed a `Sighting` (sighting.py) or plain values; none imports `topgimbal.mavlink`."""
