"""Recognition of scanned objects by their deformed circles (dissertation ch.8): geodesic-Fourier
descriptors of a scanned surface, and a gallery of labelled descriptors to identify scans against."""
