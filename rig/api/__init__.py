"""The REST API of `slrig serve` (FastAPI), versioned under /v1."""
