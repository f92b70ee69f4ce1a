"""The daemon process: the job service behind the REST API under uvicorn, the API key, and
systemd notification (ready, watchdog, stopping)."""
