"""The job service: a queue that runs scans, calibrations and reprocessing on one rig in one worker,
durable job records in SQLite, progress events, and the tasks a job (or a CLI command) runs."""
