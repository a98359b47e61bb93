"""Blender -> lightlink conversions, the same ones Blender's glTF exporter (io_scene_gltf2 3.4,
lighting mode "Standard", its default) applies, so a light sent live has the values the
exported file gave the daemon.

Frames: Blender is Z-up, glTF (and lightlink) Y-up: gltf = (x, z, -y) of Blender's world
coordinates (the exporter's "+Y Up"). A light shines along its local -Z in both.

Units (docs/units.md, docs/blender.md):
  point, spot  Blender power P [W]          -> intensity P / (4 pi) * 683 [cd]
  sun          Blender strength S [W/m^2]   -> illuminance S * 683 [lux]
  spot cone    outer = spot_size / 2, inner = outer * (1 - spot_blend)  [rad]
  range        cutoff_distance when "Custom Distance" is on, else infinite (0)
  colour       Blender's light colour (linear RGB)
Area lights have no glTF form (the exporter skips them): they are not sent.
Pure functions of plain values, importable without bpy (tests run them outside Blender too).
"""
from __future__ import annotations

import math
from typing import Dict, Optional, Sequence, Tuple

PBR_WATTS_TO_LUMENS = 683.0  # the exporter's constant (io_scene_gltf2 blender/com/gltf2_blender_conversion.py)

__all__ = ["PBR_WATTS_TO_LUMENS", "to_gltf", "intensity_from_blender", "blender_from_intensity", "light_fields"]


def to_gltf(v: Sequence[float]) -> Tuple[float, float, float]:
    """A Blender world position or direction in glTF / lightlink coordinates (Y up)."""
    return (float(v[0]), float(v[2]), -float(v[1]))


def intensity_from_blender(light_type: str, energy: float) -> float:
    """Blender power (W, point/spot) or strength (W/m^2, sun) -> cd or lux."""
    if light_type == "SUN":
        return energy * PBR_WATTS_TO_LUMENS
    if light_type in ("POINT", "SPOT"):
        return energy / (4.0 * math.pi) * PBR_WATTS_TO_LUMENS
    raise ValueError(f"light type {light_type}: not a glTF light (point, spot, sun)")


def blender_from_intensity(light_type: str, intensity: float) -> float:
    """The inverse: cd or lux -> Blender power or strength (what Blender's glTF importer does)."""
    if light_type == "SUN":
        return intensity / PBR_WATTS_TO_LUMENS
    if light_type in ("POINT", "SPOT"):
        return intensity * 4.0 * math.pi / PBR_WATTS_TO_LUMENS
    raise ValueError(f"light type {light_type}: not a glTF light (point, spot, sun)")


def light_fields(light_type: str, energy: float, color: Sequence[float], world_position: Sequence[float],
                 world_forward: Sequence[float], spot_size: float = 0.0, spot_blend: float = 0.0,
                 cutoff_distance: Optional[float] = None) -> Dict[str, object]:
    """The lightlink light (light-set field names) of a Blender light. `world_forward` is the
    light's local -Z in Blender world coordinates (where it shines)."""
    kind = {"POINT": "point", "SPOT": "spot", "SUN": "directional"}.get(light_type)
    if kind is None:
        raise ValueError(f"light type {light_type}: not a glTF light (point, spot, sun)")
    out: Dict[str, object] = {
        "type": kind,
        "color": tuple(float(c) for c in color[:3]),
        "intensity": intensity_from_blender(light_type, energy),
        "range": float(cutoff_distance) if cutoff_distance else 0.0,
    }
    if kind != "directional":
        out["position"] = to_gltf(world_position)
    if kind != "point":
        out["direction"] = to_gltf(world_forward)
    if kind == "spot":
        outer = spot_size * 0.5
        out["outer_cone_angle"] = min(outer, math.pi / 2)
        out["inner_cone_angle"] = min(outer - outer * spot_blend, out["outer_cone_angle"] * 0.999999)
    return out
