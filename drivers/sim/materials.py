"""Materials of the simulated scene: a diffuse albedo (the scene's, or a texture) and a specular
lobe, the part of the light a glossy or machined surface reflects about the mirror direction.

The lobe is Blinn-Phong, energy-normalised: radiance toward the camera per unit of the light's
irradiance at normal incidence is

    strength * (s + 8) / 8 * (n . h)^s * cos(i)

with h the half-way vector between the directions to the light and to the eye, i the angle of
incidence, and s = 2 / roughness^2 - 2 the exponent of the microfacet roughness (Walter et al.'s
mapping of Beckmann's slope to Blinn-Phong). A diffuse white surface gives 1 * cos(i) in the same
units, so a `strength` of 0.5 at roughness 0.1 peaks at about a hundred times the white's
brightness: it saturates any exposure that reads the rest of the scene.
"""

from __future__ import annotations

import numpy as np

MIN_ROUGHNESS = 0.02  # a mirror's lobe is narrower than a pixel: no sample would see it


def shininess(roughness: np.ndarray | float) -> np.ndarray:
    """The Blinn-Phong exponent of a microfacet roughness (slope rms, 0.02 to 1)."""
    r = np.maximum(np.asarray(roughness, dtype=np.float64), MIN_ROUGHNESS)
    return 2.0 / r**2 - 2.0


def specular_gain(
    normals: np.ndarray,
    to_light: np.ndarray,
    to_eye: np.ndarray,
    strength: np.ndarray,
    exponent: np.ndarray,
    irradiance: np.ndarray,
) -> np.ndarray:
    """(N,) float32 radiance of the lobe per unit of emitted light, for unit `normals`, unit
    directions to the light and to the eye (N, 3), the lobe's `strength` and Blinn-Phong
    `exponent` (N,), and the diffuse `irradiance` gain (N,: cos(i) times fall-off and brightness,
    0 where the point is unlit)."""
    half = to_light + to_eye
    half /= np.maximum(np.linalg.norm(half, axis=1, keepdims=True), 1e-12)
    cos_h = np.clip(np.einsum("ij,ij->i", normals, half), 0.0, 1.0)
    lobe = strength * (exponent + 8.0) / 8.0 * np.power(cos_h, exponent)
    return (lobe * irradiance).astype(np.float32)
