"""The simulated scene of a config: procedural shapes or a mesh file."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated, Literal

from pydantic import Field, model_validator

from rig.config.common import Albedo, Coord, Extent, Fraction, Strict, Vec3


class PlaneScene(Strict):
    kind: Literal["plane"]
    size_mm: float = Field(600.0, gt=0, le=10_000)
    albedo: Albedo = 0.7


class SphereScene(Strict):
    kind: Literal["sphere"]
    radius_mm: float = Field(60.0, gt=0, le=5_000)
    center_mm: Vec3 = (0.0, 0.0, 60.0)
    albedo: Albedo = 0.8


class BoxScene(Strict):
    kind: Literal["box"]
    extents_mm: tuple[Extent, Extent, Extent] = (120.0, 80.0, 60.0)
    rotation_deg: Vec3 = (0.0, 0.0, 25.0)
    albedo: Albedo = 0.8
    plane: bool = Field(True, description="put the box on the bench plane")


class SphereOnPlaneScene(Strict):
    kind: Literal["sphere_on_plane"]
    radius_mm: float = Field(60.0, gt=0, le=5_000)
    position_mm: tuple[Coord, Coord] = (0.0, 0.0)
    plane_size_mm: float = Field(600.0, gt=0, le=10_000)
    sphere_albedo: Albedo = (0.85, 0.75, 0.6)
    plane_albedo: Albedo = 0.6


class TerrainScene(Strict):
    kind: Literal["terrain"]
    size_mm: float = Field(400.0, gt=0, le=10_000)
    amplitude_mm: float = Field(40.0, ge=0, le=5_000)
    seed: int = Field(7, ge=0, le=2**31)
    albedo: Albedo = 0.75


class MeshScene(Strict):
    kind: Literal["mesh"]
    path: Path = Field(description="PLY, OBJ or STL; relative paths are relative to the config file")
    scale: float = Field(1.0, gt=0, le=1e6, description="mesh units to millimetres")
    fit_size_mm: float | None = Field(
        None, gt=0, le=10_000, description="if set, scale so the largest extent is this (overrides scale)"
    )
    position_mm: Vec3 = (0.0, 0.0, 0.0)
    rotation_deg: Vec3 = (0.0, 0.0, 0.0)
    albedo: Albedo = 0.8
    plane: bool = Field(True, description="put the mesh on the bench plane")


class StepsScene(Strict):
    """A staircase on the bench plane: sharp depth edges between flat treads."""

    kind: Literal["steps"]
    rises_mm: tuple[Annotated[float, Field(gt=0.0, le=500.0)], ...] = Field(
        (10.0, 15.0, 20.0, 15.0), min_length=1, max_length=50, description="each step's rise over the one before"
    )
    run_mm: float = Field(30.0, gt=0.0, le=1_000.0, description="each tread's depth")
    width_mm: float = Field(120.0, gt=0.0, le=2_000.0)
    rotation_deg: Vec3 = (0.0, 0.0, 25.0)
    albedo: Albedo = 0.8
    plane: bool = Field(True, description="put the staircase on the bench plane")


class BlocksScene(Strict):
    """A grid of touching blocks of seeded heights on the bench plane: depth edges in every direction."""

    kind: Literal["blocks"]
    count: int = Field(4, ge=1, le=20, description="blocks along each side of the grid")
    block_mm: float = Field(30.0, gt=0.0, le=1_000.0, description="each block's width and depth")
    heights_mm: tuple[Annotated[float, Field(gt=0.0, le=500.0)], Annotated[float, Field(gt=0.0, le=500.0)]] = Field(
        (5.0, 45.0), description="the least and greatest block height"
    )
    seed: int = Field(3, ge=0, le=2**31)
    rotation_deg: Vec3 = (0.0, 0.0, 10.0)
    albedo: Albedo = 0.8
    plane: bool = Field(True, description="put the blocks on the bench plane")

    @model_validator(mode="after")
    def _heights_ordered(self) -> BlocksScene:
        if self.heights_mm[0] > self.heights_mm[1]:
            raise ValueError(
                f"heights_mm: the least height {self.heights_mm[0]} exceeds the greatest {self.heights_mm[1]}"
            )
        return self


SceneShape = Annotated[
    PlaneScene | SphereScene | BoxScene | SphereOnPlaneScene | TerrainScene | StepsScene | BlocksScene | MeshScene,
    Field(discriminator="kind"),
]
SCENE_SHAPES = ("plane", "sphere", "box", "sphere_on_plane", "terrain", "steps", "blocks", "mesh")


Colour = tuple[Fraction, Fraction, Fraction]  # linear [red, green, blue]
_TWO_COLOURS: tuple[Colour, ...] = ((0.85, 0.2, 0.15), (0.15, 0.35, 0.8))


class StripesTexture(Strict):
    """Parallel bands across `direction_mm`, one of each colour per period."""

    kind: Literal["stripes"]
    period_mm: float = Field(20.0, gt=0.0, le=10_000.0)
    direction_mm: Vec3 = (1.0, 0.0, 0.0)
    colours: tuple[Colour, ...] = Field(_TWO_COLOURS, min_length=2, max_length=16)

    @model_validator(mode="after")
    def _direction(self) -> StripesTexture:
        if sum(c * c for c in self.direction_mm) < 1e-12:
            raise ValueError("direction_mm: the stripes' direction cannot be zero")
        return self


class CheckerTexture(Strict):
    """A 3D checkerboard of cubes `size_mm` on a side (squares on a plane)."""

    kind: Literal["checker"]
    size_mm: float = Field(15.0, gt=0.0, le=10_000.0)
    colours: tuple[Colour, ...] = Field(_TWO_COLOURS, min_length=2, max_length=16)


class GradientTexture(Strict):
    """Smooth colour: red, green and blue each a cosine of `period_mm` along its own direction."""

    kind: Literal["gradient"]
    period_mm: float = Field(120.0, gt=0.0, le=100_000.0)


class ImageTexture(Strict):
    """A printed image laid on the scene from above (along -z), `size_mm` wide, centred at `center_mm`."""

    kind: Literal["image"]
    path: Path = Field(description="PNG, BMP, TIFF or JPEG (sRGB); relative paths are relative to the config file")
    size_mm: float = Field(200.0, gt=0.0, le=10_000.0)
    center_mm: tuple[Coord, Coord] = (0.0, 0.0)


TextureConfig = Annotated[StripesTexture | CheckerTexture | GradientTexture | ImageTexture, Field(discriminator="kind")]


class MaterialConfig(Strict):
    """The scene's objects beside their albedo: a specular lobe (drivers.sim.materials). The bench
    plane stays matte unless `bench`."""

    specular: float = Field(0.0, ge=0.0, le=1.0, description="strength of the specular lobe; 0: matte")
    roughness: float = Field(
        0.3, ge=0.02, le=1.0, description="microfacet roughness: about 0.05 polished metal, 0.3 satin, 1 matte"
    )
    bench: bool = Field(False, description="the bench plane is glossy too")


class SimulationConfig(Strict):
    scene: SceneShape
    material: MaterialConfig = Field(default_factory=MaterialConfig)
    texture: TextureConfig | None = Field(
        None, description="paint the whole scene with a procedural texture (in place of its albedo)"
    )
    ambient: float = Field(0.02, ge=0.0, le=10.0, description="ambient irradiance, relative to white")
    seed: int = Field(1, ge=0, le=2**31)
