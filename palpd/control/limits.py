"""Limits fixed at start-up: the workspace box, and configurations refused because no supervisor could make
them safe (a force cap the sensor cannot measure, tissue out of reach, a rest pose not clear of the tissue)."""
from __future__ import annotations

from drivers.phantom import model
from palpd.errors import ConfigError

NANO17_FORCE_RANGE_N = (25.0, 25.0, 35.0)  # SI-25-0.25, when a sensor does not say its own


def workspace_box_mm(settings, tissue_size_mm, home_mm) -> tuple[tuple[float, float], ...]:
    """(x, y, z) ranges in the tissue frame: the tissue plus a margin, the z band, and the arm's home."""
    margin = settings.workspace_margin_mm
    half_x, half_y = tissue_size_mm[0] / 2 + margin, tissue_size_mm[1] / 2 + margin
    z_low, z_high = settings.workspace_z_mm
    return ((min(-half_x, home_mm[0] - margin), max(half_x, home_mm[0] + margin)),
            (min(-half_y, home_mm[1] - margin), max(half_y, home_mm[1] + margin)),
            (z_low, max(z_high, home_mm[2] + margin)))


def rest_pose_mm(frame) -> tuple[float, float, float]:
    """Where the tip rests at home (in its stand, all joints zero), in the tissue frame."""
    return tuple(1000.0 * v for v in frame.from_robot(model.forward(model.HOME_Q)))  # type: ignore[return-value]


def refuse_unsafe_configuration(settings, frame, force_range_n=NANO17_FORCE_RANGE_N) -> None:
    """Raise ConfigError (one line) for a force cap the sensor cannot measure, a palpable area out of reach
    or a rest pose where a parked (unpowered) arm would not be clear of the tissue."""
    cap, weakest_axis_n = settings.safety.force_cap_n, min(force_range_n)
    if cap >= weakest_axis_n:
        raise ConfigError(f"safety.force_cap_n = {cap} N is not below the force sensor's range of "
                          f"{weakest_axis_n} N, so a harder push could not be measured")
    rest_z_mm = rest_pose_mm(frame)[2]
    if rest_z_mm < settings.palpation.clearance_mm:
        raise ConfigError(f"tissue.origin_mm {list(settings.tissue.origin_mm)}: the arm's rest pose is "
                          f"{rest_z_mm:.1f} mm above the tissue, below palpation.clearance_mm, so a stop "
                          "could not park it clear of the tissue")
    half_x, half_y = settings.tissue.size_mm[0] / 2, settings.tissue.size_mm[1] / 2
    z_low = max(settings.safety.workspace_z_mm[0], -settings.palpation.depth_mm)
    for x in (-half_x, half_x):
        for y in (-half_y, half_y):
            for z in (z_low, settings.palpation.clearance_mm):
                try:
                    model.inverse(frame.to_robot((x / 1000.0, y / 1000.0, z / 1000.0)))
                except model.UnreachableError as exc:
                    raise ConfigError(f"tissue.origin_mm {list(settings.tissue.origin_mm)} with size_mm "
                                      f"{list(settings.tissue.size_mm)}: corner ({x:g}, {y:g}, {z:g}) mm is "
                                      f"outside the arm's reach ({exc})") from None
