"""The job queue: a huey instance chosen by settings (SQLite or Redis), one thin
task that runs a job by id, the lease that keeps a job's state honest, and the
worker entry point. All job state lives in the database; the queue carries ids.
"""
