"""MISB ST 0601's sensor angles: the camera's attitude relative to the platform's axes.

ST 0601 gives the platform's heading, pitch and roll (tags 5-7) and the sensor's relative azimuth,
elevation and roll (tags 18-20); a player finds the line of sight by applying them in turn, each an
aerospace Z-Y-X rotation: earth <- platform (heading, pitch, roll) <- sensor (azimuth, elevation,
roll). So the relative angles are the Euler angles of R_platform^T * R_sensor_earth, not the
differences of earth angles (which differ as soon as the platform pitches or rolls: 1.6 deg of line
of sight at the median with 2 deg of roll and -3 deg of pitch)."""

from __future__ import annotations

from .frames import Attitude, Mat, euler_matrix, matmul, to_euler


def transpose(m: Mat) -> Mat:
    return ((m[0][0], m[1][0], m[2][0]), (m[0][1], m[1][1], m[2][1]), (m[0][2], m[1][2], m[2][2]))


def sensor_relative_deg(platform: Attitude, sensor_earth: Attitude) -> tuple[float, float, float]:
    """(azimuth 0..360, elevation -90..90, roll 0..360) in degrees: tags 18, 19, 20 for a camera
    whose earth-frame attitude is `sensor_earth` on a platform at `platform`."""
    p = euler_matrix(platform.roll_deg, platform.pitch_deg, platform.yaw_deg)
    s = euler_matrix(sensor_earth.roll_deg, sensor_earth.pitch_deg, sensor_earth.yaw_deg)
    roll, elevation, azimuth = to_euler(matmul(transpose(p), s))
    return azimuth % 360.0, elevation, roll % 360.0
