"""Rig assembly: a config's devices built through the driver table (rig.config.drivers), in the
real world or on the simulated bench, into an open Rig."""

from rig.assembly.build import geometry_model, open_rig, rig_geometry
from rig.assembly.world import World

__all__ = ["World", "geometry_model", "open_rig", "rig_geometry"]
