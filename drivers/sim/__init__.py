"""The simulated bench: a physical model of projectors, cameras and a scene, with ground truth.

`SimBench` holds the scene and the device geometry; `SimProjector` and `SimCamera` implement the same
interfaces as real devices. Device geometry is given as objects with the `ViewModel` protocol
(rig.geometry.CameraModel satisfies it), and photometry as the config's own `sim` sections
(drivers.options), so this package does not depend on `rig`. It loads trimesh and Embree: of runtime
code only the assembly of a simulated rig (rig.assembly.simulated) and the view planner import it.
"""
