"""A child process that must not outlive its parent: the kernel ends it when the parent ends.

Used by every process that works for another one: a detection's pool processes
(for the process that detects), a service's job processes (for their worker) and
workers (for `freecal serve`). Without it a parent killed outright (SIGKILL, out
of memory) leaves its children running alone, holding cores and files.
"""
from __future__ import annotations

import os
import signal
from typing import Any

PR_SET_PDEATHSIG = 1  # <linux/prctl.h>


def die_with_parent(parent_pid: int | None = None) -> bool:
    """Linux: SIGKILL this process when its parent ends; True when armed.

    ``parent_pid``: the parent expected; if it already ended before the request was made (a race with
    the kernel's re-parenting), this process ends now, as the signal would have ended it.
    Elsewhere False: callers keep their own check (the worker polls its parent's pid).
    """
    try:
        import ctypes

        if ctypes.CDLL(None, use_errno=True).prctl(PR_SET_PDEATHSIG, signal.SIGKILL) != 0:
            return False
    except (OSError, AttributeError):
        return False
    if parent_pid is not None and os.getppid() != parent_pid:
        os._exit(1)
    _release_fork_server()
    return True


def _release_fork_server() -> None:
    """A fork server's child inherits the server's "alive" pipe, and the server runs until every holder
    of that pipe has ended: its children too, not only the process that started it. So a job process
    kept the fork server (its parent) alive after the worker was killed, and the job ran on alone.
    Given up here, the server ends with the process that started it, and this child with the server.
    (The child can still run processes of its own: multiprocessing starts it a fork server of its own.)"""
    try:
        from multiprocessing import forkserver

        server: Any = forkserver._forkserver  # private state, which typeshed does not declare
        if server._forkserver_pid is None and server._forkserver_alive_fd is not None:  # inherited, not ours
            os.close(server._forkserver_alive_fd)
            server._forkserver_alive_fd = server._forkserver_address = None
    except (AttributeError, OSError):
        pass  # another Python's internals: the child then lives as long as its fork server
