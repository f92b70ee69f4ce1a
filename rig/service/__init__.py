"""The daemon: a job queue that runs scans, calibrations and reprocessing on one rig, durable job
records in SQLite, progress events, systemd notification."""
