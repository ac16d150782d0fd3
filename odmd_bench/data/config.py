"""Camera and generator configurations: frozen, validated on creation, (de)serialisable.

A configuration that the generator could not honour (an object that would leave the
view, a minimum above a maximum, fewer than two observations, an unknown key in a
file) raises :class:`~odmd_bench.errors.ConfigError` naming the field, at creation,
never later inside the generator.
"""

from __future__ import annotations

import json
import math
from collections.abc import Mapping
from dataclasses import asdict, dataclass, field, fields
from pathlib import Path
from typing import Any

from odmd_bench.errors import ConfigError, show_value

Vec3 = tuple[float, float, float]
Range = tuple[float, float]


#: The most observations an example may have (the paper uses 10).
MAX_N_OBS = 1000


def _finite(name: str, value: Any, problems: list[str]) -> None:
    if isinstance(value, bool) or not isinstance(value, int | float) or not math.isfinite(value):
        problems.append(f"{name}: expected a finite number, got {show_value(value)}")


@dataclass(frozen=True)
class CameraConfig:
    """A pinhole camera: image size and intrinsics, in pixels."""

    image_width: int
    image_height: int
    fx: float
    fy: float
    cx: float
    cy: float

    def __post_init__(self) -> None:
        problems: list[str] = []
        for name in ("image_width", "image_height"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, int) or v <= 0:
                problems.append(f"camera.{name}: expected a positive integer, got {v!r}")
        for name in ("fx", "fy", "cx", "cy"):
            _finite(f"camera.{name}", getattr(self, name), problems)
        if not problems:
            if self.fx <= 0 or self.fy <= 0:
                problems.append(f"camera.fx/fy: must be positive, got {self.fx}, {self.fy}")
            if not 0 < self.cx < self.image_width:
                problems.append(f"camera.cx: must lie inside (0, {self.image_width}), got {self.cx}")
            if not 0 < self.cy < self.image_height:
                problems.append(f"camera.cy: must lie inside (0, {self.image_height}), got {self.cy}")
        if problems:
            raise ConfigError("invalid camera configuration", problems)


#: The Toyota HSR grasp camera of the paper (factory intrinsics, 480x640 images).
HSR_GRASP_CAMERA = CameraConfig(image_width=640, image_height=480, fx=205.5, fy=205.5, cx=320.5, cy=240.5)


@dataclass(frozen=True)
class GeneratorConfig:
    """What the ODMD generator draws from (paper section 3.3, supplementary material).

    Attributes:
        camera: the camera the boxes are projected with.
        n_obs: observations per example (>= 2).
        object_size: (s_min, s_max) of the object's width and height, metres.
        initial_depth: (Z1_min, Z1_max) of the depth at the first observation, metres.
        move_min, move_max: per-axis bounds of the total camera move |p_n - p_1|, metres.
        camera_sigma: standard deviation of camera-position noise, metres.
        box_sigma: standard deviation of box noise, normalised image units.
        replace_prob: probability that one box of an example is replaced by the box
            another example has at the same observation.
        reverse_prob: probability that an example's observations are reversed.
    """

    camera: CameraConfig = HSR_GRASP_CAMERA
    n_obs: int = 10
    object_size: Range = (0.01, 0.175)
    initial_depth: Range = (0.55, 1.0)
    move_min: Vec3 = (0.0, 0.0, 0.05)
    move_max: Vec3 = (0.25, 0.175, 0.325)
    camera_sigma: float = 0.01
    box_sigma: float = 0.001
    replace_prob: float = 0.1
    reverse_prob: float = 0.5

    def __post_init__(self) -> None:
        problems: list[str] = []
        if not isinstance(self.camera, CameraConfig):
            problems.append(f"camera: expected a CameraConfig, got {type(self.camera).__name__}")
        if (
            isinstance(self.n_obs, bool)
            or not isinstance(self.n_obs, int)
            or not 2 <= self.n_obs <= MAX_N_OBS
        ):
            problems.append(f"n_obs: expected an integer from 2 to {MAX_N_OBS}, got {show_value(self.n_obs)}")
        typed: set[str] = set()  # the fields whose type is right, checked further below
        for name, size in (("object_size", 2), ("initial_depth", 2), ("move_min", 3), ("move_max", 3)):
            value = getattr(self, name)
            if not isinstance(value, tuple) or len(value) != size:
                problems.append(f"{name}: expected {size} numbers, got {show_value(value)}")
                continue
            before = len(problems)
            for i, v in enumerate(value):
                _finite(f"{name}[{i}]", v, problems)
            if len(problems) == before:
                typed.add(name)
        for name in ("camera_sigma", "box_sigma", "replace_prob", "reverse_prob"):
            before = len(problems)
            _finite(name, getattr(self, name), problems)
            if len(problems) == before:
                typed.add(name)

        if "object_size" in typed and not 0 < self.object_size[0] <= self.object_size[1]:
            problems.append(f"object_size: need 0 < min <= max, got {self.object_size}")
        if "initial_depth" in typed and not 0 < self.initial_depth[0] <= self.initial_depth[1]:
            problems.append(f"initial_depth: need 0 < min <= max, got {self.initial_depth}")
        if {"move_min", "move_max"} <= typed:
            for axis, (a, b) in enumerate(zip(self.move_min, self.move_max, strict=True)):
                if not 0 <= a <= b:
                    problems.append(
                        f"move_min[{axis}]/move_max[{axis}]: need 0 <= min <= max, got ({a}, {b})"
                    )
        for name in ("camera_sigma", "box_sigma"):
            if name in typed and getattr(self, name) < 0:
                problems.append(f"{name}: must be >= 0, got {getattr(self, name)}")
        for name in ("replace_prob", "reverse_prob"):
            if name in typed and not 0 <= getattr(self, name) <= 1:
                problems.append(f"{name}: must lie in [0, 1], got {getattr(self, name)}")
        if problems:
            raise ConfigError("invalid generator configuration", problems)
        problems.extend(self._view_problems())
        if problems:
            raise ConfigError("generator configuration cannot keep the object in view", problems)

    def _view_problems(self) -> list[str]:
        # Supplementary material, "Camera-based Constraints": X1 and Y1 are drawn from
        # [X1min(Z1), X1max(Z1)]; the box stays in view at every observation only if
        # that interval is non-empty. Its width grows with Z1, so Z1 = Z1_min decides:
        # (W_I / fx)(Z1_min - dCz_max) >= 2 dCx_max + s_max, likewise for y.
        cam = self.camera
        z_room = self.initial_depth[0] - self.move_max[2]
        s_max = self.object_size[1]
        out = []
        for axis, size, f in (("x", cam.image_width, cam.fx), ("y", cam.image_height, cam.fy)):
            need = 2 * self.move_max[0 if axis == "x" else 1] + s_max
            have = size / f * z_room
            if have < need:
                z_min = self.move_max[2] + need * f / size
                out.append(
                    f"initial_depth[0]: {self.initial_depth[0]} m is too close for the {axis} axis: "
                    f"with move_max={self.move_max} and object_size max {s_max} the object can "
                    f"leave the image; it must be at least {z_min:.6f} m"
                )
        return out

    def to_dict(self) -> dict[str, Any]:
        """Plain, JSON-ready dict (tuples become lists)."""
        d = asdict(self)
        return json.loads(json.dumps(d))

    def to_json(self) -> str:
        """Canonical JSON: sorted keys, no spaces."""
        return json.dumps(self.to_dict(), sort_keys=True, separators=(",", ":"))

    @classmethod
    def from_dict(cls, data: Mapping[str, Any], *, base: GeneratorConfig | None = None) -> GeneratorConfig:
        """Build from a mapping; keys left out take ``base``'s values (default: preset ``odmd``).

        Unknown keys, at either level, are an error naming them.
        """
        if not isinstance(data, Mapping):
            raise ConfigError(f"a generator configuration must be a mapping, got {type(data).__name__}")
        base = base or PRESETS["odmd"]
        known = {f.name for f in fields(cls)}
        problems = [f"key {show_value(k)} is not a name" for k in data if not isinstance(k, str)]
        unknown = sorted(k for k in data if isinstance(k, str) and k not in known)
        problems += [f"unknown key {k!r} (known: {', '.join(sorted(known))})" for k in unknown]
        camera = base.camera
        if "camera" in data:
            cam = data["camera"]
            cam_known = {f.name for f in fields(CameraConfig)}
            if not isinstance(cam, Mapping):
                problems.append(f"camera: expected a mapping, got {show_value(cam)}")
            else:
                problems += [
                    f"camera: key {show_value(k)} is not a name" for k in cam if not isinstance(k, str)
                ]
                problems += [
                    f"unknown key 'camera.{k}' (known: {', '.join(sorted(cam_known))})"
                    for k in sorted(k for k in cam if isinstance(k, str) and k not in cam_known)
                ]
        if problems:
            raise ConfigError("invalid generator configuration", problems)
        if "camera" in data:
            try:
                camera = CameraConfig(**{**asdict(base.camera), **dict(data["camera"])})
            except ConfigError as e:  # reported with the other fields' problems
                problems += e.problems or [e.message]
        values: dict[str, Any] = {f.name: getattr(base, f.name) for f in fields(cls)}
        for k, v in data.items():
            if k == "camera":
                continue
            values[k] = tuple(v) if isinstance(v, list) else v
        values["camera"] = camera
        try:
            config = cls(**values)
        except ConfigError as e:
            raise ConfigError(e.message, problems + e.problems) from None
        if problems:
            raise ConfigError("invalid generator configuration", problems)
        return config

    @classmethod
    def from_file(cls, path: str | Path) -> GeneratorConfig:
        """Read a ``.json``, ``.yaml`` or ``.yml`` file (a mapping of the fields)."""
        from odmd_bench.documents import MAX_DOCUMENT_BYTES, DocumentError, load_document

        p = Path(path)
        suffix = p.suffix.lower()
        kinds = {".json": "json", ".yaml": "yaml", ".yml": "yaml"}
        if suffix not in kinds:
            raise ConfigError(f"{p}: unknown configuration format {suffix!r}; use .json, .yaml or .yml")
        try:
            with p.open("rb") as fh:
                raw = fh.read(MAX_DOCUMENT_BYTES + 1)
        except OSError as e:
            raise ConfigError(
                f"cannot read configuration file {p}: {e.strerror or type(e).__name__}"
            ) from None
        try:
            data: Any = load_document(raw, kinds[suffix])
        except DocumentError as e:
            raise ConfigError(f"{p}: not valid {kinds[suffix].upper()}: {e}") from None
        return cls.from_dict(data or {})

    def write(self, path: str | Path) -> None:
        """Write as JSON or YAML, chosen by the file's suffix."""
        p = Path(path)
        if p.suffix.lower() in (".yaml", ".yml"):
            import yaml

            p.write_text(yaml.safe_dump(self.to_dict(), sort_keys=True), encoding="utf-8")
        elif p.suffix.lower() == ".json":
            p.write_text(json.dumps(self.to_dict(), indent=2, sort_keys=True) + "\n", encoding="utf-8")
        else:
            raise ConfigError(f"{p}: unknown configuration format {p.suffix!r}; use .json, .yaml or .yml")


PRESETS: dict[str, GeneratorConfig] = {}
#: The paper's standard x, y, z configuration (Normal set, HSR grasp camera).
PRESETS["odmd"] = GeneratorConfig()
#: z-only motion for the ODMS benchmark (paper, DBox_p^z): move max (0, 0, 0.4625) m,
#: fx = fy = 240.5. The paper's Z1_min = 0.55 m leaves the y interval of X1min/X1max
#: empty by 0.36 mm for these numbers (an object of s_max could graze the image edge),
#: so the preset starts at 0.5505 m, the smallest round value that keeps it in view.
PRESETS["odms"] = GeneratorConfig(
    camera=CameraConfig(image_width=640, image_height=480, fx=240.5, fy=240.5, cx=320.5, cy=240.5),
    initial_depth=(0.5505, 1.0),
    move_max=(0.0, 0.0, 0.4625),
)


def get_preset(preset: str | GeneratorConfig) -> GeneratorConfig:
    """Return a preset by name, or the config itself."""
    if isinstance(preset, GeneratorConfig):
        return preset
    try:
        return PRESETS[preset]
    except (KeyError, TypeError):
        raise ConfigError(
            f"unknown preset {preset!r}; expected one of {', '.join(sorted(PRESETS))} or a GeneratorConfig"
        ) from None


PERTURBATIONS = ("normal", "camera", "object", "both")


def check_perturbation(perturbation: str) -> str:
    """Return ``perturbation``; raise :class:`ConfigError` unless it is one of :data:`PERTURBATIONS`."""
    if perturbation not in PERTURBATIONS:
        raise ConfigError(
            f"unknown perturbation {perturbation!r}; expected one of {', '.join(PERTURBATIONS)}"
        )
    return perturbation


__all__ = [
    "CameraConfig",
    "GeneratorConfig",
    "HSR_GRASP_CAMERA",
    "PERTURBATIONS",
    "PRESETS",
    "check_perturbation",
    "get_preset",
    "field",
]
