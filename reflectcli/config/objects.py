"""Scene objects: primitives, the teapot, mesh files, procedural clutter; transforms and motion."""

from __future__ import annotations

from typing import Annotated, Literal

from pydantic import Field, model_validator

from .base import PositiveInt, Strict, Vec2, Vec3, array_of


class Transform(Strict):
    """Object -> world: scale, then rotate about x, then y, then z (degrees), then translate.

    As a matrix: M = T @ Rz @ Ry @ Rx @ S.
    """

    translate: Vec3 = (0.0, 0.0, 0.0)
    rotate: Vec3 = (0.0, 0.0, 0.0)
    scale: float | Vec3 = 1.0


class TransformKey(Transform):
    """A keyframed transform; frames between keys interpolate each component linearly."""

    frame: int = Field(ge=0)


class _Object(Strict):
    name: str
    material: str
    transform: Transform = Transform()
    motion: list[TransformKey] | None = Field(
        default=None, description="keyframed transforms over the frame range; replaces transform"
    )

    @model_validator(mode="after")
    def _keys_ordered(self):
        if self.motion is not None:
            frames = [k.frame for k in self.motion]
            if not frames or frames != sorted(set(frames)):
                raise ValueError("motion keys need strictly increasing frame numbers")
        return self


class QuadObject(_Object):
    shape: Literal["quad"]
    corners: array_of(Vec3, Vec3, Vec3, Vec3)
    uv: array_of(Vec2, Vec2, Vec2, Vec2) = ((0, 0), (1, 0), (1, 1), (0, 1))


class BoxObject(_Object):
    shape: Literal["box"]
    min: Vec3
    max: Vec3


RoomFace = Literal["floor", "ceiling", "north", "south", "west", "east"]


class RoomObject(_Object):
    """A box seen from inside; `faces` leaves some walls out."""

    shape: Literal["room"]
    min: Vec3
    max: Vec3
    faces: list[RoomFace] = ["floor", "ceiling", "north", "south", "west", "east"]


class SphereObject(_Object):
    shape: Literal["sphere"]
    radius: float = Field(default=1.0, gt=0)
    tessellation: Literal["uv", "ico"] = "uv"
    segments: PositiveInt = 32
    subdivisions: int = Field(default=3, ge=0, le=7)


class CylinderObject(_Object):
    shape: Literal["cylinder"]
    radius: float = Field(default=1.0, gt=0)
    height: float = Field(default=1.0, gt=0)
    segments: PositiveInt = 32
    caps: bool = True


class ConeObject(_Object):
    shape: Literal["cone"]
    radius: float = Field(default=1.0, gt=0)
    height: float = Field(default=1.0, gt=0)
    segments: PositiveInt = 32


class PyramidObject(_Object):
    shape: Literal["pyramid"]
    size: float = Field(default=1.0, gt=0)
    height: float = Field(default=1.0, gt=0)


class TorusObject(_Object):
    shape: Literal["torus"]
    major_radius: float = Field(default=1.0, gt=0)
    minor_radius: float = Field(default=0.25, gt=0)
    major_segments: PositiveInt = 48
    minor_segments: PositiveInt = 16


class TeapotObject(_Object):
    """The Utah teapot in its native frame (z up): rotate [-90, 0, 0] to stand it on y."""

    shape: Literal["teapot"]
    subdivisions: PositiveInt = 8


class Fit(Strict):
    """Scale a mesh uniformly so its largest extent is `size`, centred on `center`
    (object space: the object's transform applies after)."""

    center: Vec3 = (0.0, 0.0, 0.0)
    size: float = Field(gt=0, le=1e6, description="largest extent after fitting")


class MeshObject(_Object):
    shape: Literal["mesh"]
    path: str = Field(description="OBJ, PLY, GLB or STL, relative to the scene file")
    fit: Fit | None = Field(default=None, description="centre and size in the scene's units")


class ClutterObject(_Object):
    """Procedural music-room furniture with about `triangles` triangles inside the bounds."""

    shape: Literal["clutter"]
    triangles: int = Field(default=190_000, ge=500, le=20_000_000)
    min: Vec3
    max: Vec3
    seed: int = Field(default=7, ge=0, description="placement jitter (numpy generator seed)")


ObjectConfig = Annotated[
    QuadObject
    | BoxObject
    | RoomObject
    | SphereObject
    | CylinderObject
    | ConeObject
    | PyramidObject
    | TorusObject
    | TeapotObject
    | MeshObject
    | ClutterObject,
    Field(discriminator="shape"),
]
