"""Reading ATI .cal XML files into a Calibration; every problem is one line naming the file."""
from __future__ import annotations

import xml.etree.ElementTree as ElementTree
from pathlib import Path

import numpy as np

from drivers.errors import DriverInitializationError
from dataclasses import replace

from drivers.nano17.calibration import AXES, Calibration, tool_transform


def load_calibration(path: str | Path) -> Calibration:
    path = Path(path)
    try:
        root = ElementTree.parse(path).getroot()
    except FileNotFoundError:
        raise DriverInitializationError(f"{path}: calibration file not found") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise DriverInitializationError(f"{path}: cannot read calibration file: {exc}") from None
    except ElementTree.ParseError as exc:
        raise DriverInitializationError(f"{path}: not an ATI calibration file (bad XML: {exc})") from None
    try:
        return _from_xml(root)
    except (KeyError, ValueError) as exc:
        raise DriverInitializationError(f"{path}: {exc}") from None


def _from_xml(root) -> Calibration:
    if root.tag != "FTSensor":
        raise ValueError(f"not an ATI calibration file (root element <{root.tag}>, expected <FTSensor>)")
    calibration = root.find("Calibration")
    if calibration is None:
        raise ValueError("no <Calibration> element")
    gauges = int(root.get("NumGages", "6"))
    user_rows = _rows(calibration, "UserAxis", gauges)
    axis_rows = _rows(calibration, "Axis", gauges)
    if user_rows is None and axis_rows is None:
        raise ValueError("neither UserAxis nor Axis rows found")
    transform = _basic_transform(calibration)
    axis_matrix = None
    if axis_rows is not None:
        scales = np.array([float(_attribute(e, "scale")) for e in _elements(calibration, "Axis")])
        axis_matrix = axis_rows / scales[:, None]
    source = "UserAxis" if user_rows is not None else "Axis"
    ranges = tuple(float(_attribute(e, "max")) for e in _elements(calibration, source))
    partial = Calibration(
        serial=root.get("Serial", ""), body_style=root.get("BodyStyle", ""),
        part_number=calibration.get("PartNumber", ""), force_units=calibration.get("ForceUnits", "N"),
        torque_units=calibration.get("TorqueUnits", "N-mm"), dist_units=calibration.get("DistUnits", "mm"),
        gauges=gauges, matrix=user_rows if user_rows is not None else np.zeros((6, gauges)), ranges=ranges,
        axis_matrix=axis_matrix, basic_transform=transform,
        output_range_v=float(calibration.get("OutputRange", "20")),
        bipolar=calibration.get("OutputBipolar", "True").lower() == "true",
    )
    if user_rows is None:  # only raw rows: the user matrix is them with the BasicTransform applied
        matrix = tool_transform(transform[:3], transform[3:], partial._dist_in_torque_units()) @ axis_matrix
        return replace(partial, matrix=matrix)
    return partial


def _elements(calibration, tag: str) -> list:
    by_name = {e.get("Name"): e for e in calibration.findall(tag)}
    return [by_name[name] for name in AXES]


def _rows(calibration, tag: str, gauges: int) -> np.ndarray | None:
    if not calibration.findall(tag):
        return None
    names = {e.get("Name") for e in calibration.findall(tag)}
    missing = [a for a in AXES if a not in names]
    if missing:
        raise ValueError(f"{tag} rows missing for {', '.join(missing)}")
    rows = []
    for element in _elements(calibration, tag):
        values = [float(v) for v in _attribute(element, "values").split()]
        if len(values) != gauges:
            raise ValueError(f"{tag} {element.get('Name')} has {len(values)} values, expected {gauges} (NumGages)")
        rows.append(values)
    return np.array(rows)


def _basic_transform(calibration) -> tuple[float, ...]:
    element = calibration.find("BasicTransform")
    if element is None:
        return (0.0,) * 6
    return tuple(float(element.get(key, "0")) for key in ("Dx", "Dy", "Dz", "Rx", "Ry", "Rz"))


def _attribute(element, name: str) -> str:
    value = element.get(name)
    if value is None:
        raise ValueError(f"<{element.tag} Name={element.get('Name')!r}> has no {name} attribute")
    return value
