"""One router per resource: sets, jobs (and their result files), health."""
