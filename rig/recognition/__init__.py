"""Recognition of scanned objects by their deformed circles (dissertation ch.8): geodesic-Fourier
descriptors of a scanned surface, and a gallery of labelled descriptors to identify scans against."""

from rig.lazy import face

# The names other packages use, each imported from its module when first read (rig.lazy.face).
_LAZY = {
    "Comparison": "identify",
    "Descriptor": "descriptor",
    "DescriptorSettings": "descriptor",
    "EMPTY_GALLERY": "identify",
    "Entry": "gallery",
    "GALLERY_NAME": "gallery",
    "Gallery": "gallery",
    "Identification": "identify",
    "LABEL": "gallery",
    "UNKNOWN": "identify",
    "describe": "descriptor",
    "matrix_of": "matrix",
}
__getattr__, __dir__ = face(__name__, _LAZY)

__all__ = [
    "EMPTY_GALLERY",
    "GALLERY_NAME",
    "LABEL",
    "UNKNOWN",
    "Comparison",
    "Descriptor",
    "DescriptorSettings",
    "Entry",
    "Gallery",
    "Identification",
    "describe",
    "matrix_of",
]
