"""TI DLP projector controllers."""
