"""Mirrors: planar (quad, rectangle) and curved (sphere, cylinder, extrusion, cap, mesh)."""

from __future__ import annotations

from typing import Annotated, Literal

from pydantic import Field

from .base import Color, PositiveInt, Strict, UnitFloat, Vec2, Vec3, array_of
from .objects import Transform


class _Mirror(Strict):
    """final = (1 - r) * base + r * reflected, per channel."""

    name: str
    reflectance: UnitFloat | array_of(UnitFloat, UnitFloat, UnitFloat) = 1.0
    base: Color = (0.0, 0.0, 0.0)

    @property
    def reflectance_rgb(self) -> tuple[float, float, float]:
        r = self.reflectance
        return (r, r, r) if isinstance(r, float | int) else tuple(r)

    @property
    def planar(self) -> bool:
        return False


class QuadMirror(_Mirror):
    shape: Literal["quad"]
    corners: array_of(Vec3, Vec3, Vec3, Vec3)

    @property
    def planar(self) -> bool:
        return True


class RectangleMirror(_Mirror):
    """Centered at `center`, facing `normal`; `size` = (width along up x normal, height)."""

    shape: Literal["rectangle"]
    center: Vec3
    normal: Vec3
    up: Vec3 = (0.0, 1.0, 0.0)
    size: array_of(Annotated[float, Field(gt=0)], Annotated[float, Field(gt=0)])

    @property
    def planar(self) -> bool:
        return True


class SphereMirror(_Mirror):
    """Exact in the ray tracer; `segments` tessellates it for rasterizing techniques."""

    shape: Literal["sphere"]
    center: Vec3
    radius: float = Field(gt=0)
    segments: PositiveInt = 64


class CylinderMirror(_Mirror):
    """An open tube from `origin` along unit `axis` for `height`; exact in the ray tracer."""

    shape: Literal["cylinder"]
    origin: Vec3 = (0.0, 0.0, 0.0)
    axis: Vec3 = (0.0, 1.0, 0.0)
    radius: float = Field(gt=0)
    height: float = Field(gt=0)
    segments: PositiveInt = 64


class MeshMirror(_Mirror):
    """A triangle mesh reflector; `smooth` interpolates vertex normals across faces."""

    shape: Literal["mesh"]
    path: str
    transform: Transform = Transform()
    smooth: bool = True


class ExtrusionMirror(_Mirror):
    """A linear extrusion of a planar polyline (Ofek & Rappoport's TV screen, Fig. 17).

    In local space the polyline `profile` ([x, z] points) lies in the xz plane and is swept
    along +y from y = 0 to y = `height`; `transform` places it in the world. The reflecting
    front is to the LEFT of the polyline's direction seen from +y (looking down -y): a
    profile running toward -x faces +z. Normals are smooth: per profile point the average of
    its segments' normals. `subdivisions` rows of triangles along the height. Built as a
    triangle mesh, traced as triangles with interpolated normals.
    """

    shape: Literal["extrusion"]
    profile: list[Vec2]
    height: float = Field(gt=0)
    transform: Transform = Transform()
    subdivisions: PositiveInt = 1


class CapMirror(_Mirror):
    """A spherical cap: the part of the sphere (`center`, `radius`) within `angle` degrees
    (half-angle, 0 < angle <= 180) of the pole center + radius * `axis`. `concave`: the
    reflecting side is the inside (normals point to the center); else the outside.
    `segments` facets around the axis (rings at the same angular spacing). Built as a
    triangle mesh, traced as triangles with interpolated normals.
    """

    shape: Literal["cap"]
    center: Vec3 = (0.0, 0.0, 0.0)
    radius: float = Field(gt=0)
    axis: Vec3 = (0.0, 1.0, 0.0)
    angle: float = Field(gt=0, le=180)
    concave: bool = False
    segments: PositiveInt = 64


MirrorConfig = Annotated[
    QuadMirror
    | RectangleMirror
    | SphereMirror
    | CylinderMirror
    | ExtrusionMirror
    | CapMirror
    | MeshMirror,
    Field(discriminator="shape"),
]
