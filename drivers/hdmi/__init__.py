"""HDMI pattern output: any projector as a display, driven by a separate worker process."""
