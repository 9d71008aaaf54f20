"""`topgimbal sim --fleet N --udp HOST:PORT`: N cameras in one process, each its own device on its
own port (a setting changed on one is not on the others), and the options it refuses."""

from __future__ import annotations

import argparse
import signal
import socket
import subprocess
import sys

import pytest

from topgimbal.cli.sim_fleet import FleetArgsError, check_fleet_args, fleet_ports

from .conftest import LOOP, req

pytestmark = pytest.mark.loopback


def test_ports_follow_the_first_and_zero_means_free_ports() -> None:
    assert fleet_ports([(LOOP, 6000)], 3) == [(LOOP, 6000), (LOOP, 6001), (LOOP, 6002)]
    assert fleet_ports([(LOOP, 0)], 2) == [(LOOP, 0), (LOOP, 0)]
    with pytest.raises(FleetArgsError, match="beyond 65535"):
        fleet_ports([(LOOP, 65535)], 2)
    with pytest.raises(FleetArgsError, match="exactly one --udp"):
        fleet_ports(None, 2)
    with pytest.raises(FleetArgsError, match="exactly one --udp"):
        fleet_ports([(LOOP, 1), (LOOP, 2)], 2)


def test_options_of_one_camera_are_refused() -> None:
    args = argparse.Namespace(udp=[(LOOP, 0)], fleet=2, state="s.json", truth=None, tcp=None, serial=None)
    with pytest.raises(FleetArgsError, match="--state"):
        check_fleet_args(args)


def test_each_camera_answers_on_its_own_port_with_its_own_state() -> None:
    proc = subprocess.Popen(
        [sys.executable, "-m", "topgimbal.cli.main", "sim", "--model", "sip", "--fleet", "3", "--udp", f"{LOOP}:0"],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
    )  # fmt: skip
    try:
        assert proc.stdout is not None
        urls = [proc.stdout.readline().strip() for _ in range(3)]
        assert all(u.startswith(f"udp://{LOOP}:") for u in urls), urls
        ports = [int(u.rsplit(":", 1)[1]) for u in urls]
        assert len(set(ports)) == 3
        with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
            s.bind((LOOP, 0))
            s.settimeout(10)
            s.sendto(req("SIP", "GTW", address="10.0.0.254"), (LOOP, ports[1]))  # only the second camera
            assert b"GTW10.0.0.254" in s.recv(100)
            for port in (ports[0], ports[2]):
                s.sendto(req("SIP", "GTW", read=True), (LOOP, port))  # a read: each camera its own setting
                answer = s.recv(100)
                assert b"GTW" in answer and b"10.0.0.254" not in answer
    finally:
        proc.send_signal(signal.SIGTERM)
        assert proc.wait(20) == 0
