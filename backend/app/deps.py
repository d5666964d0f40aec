"""Dependencies as Annotated aliases: handlers declare what they need by type."""
from __future__ import annotations

from typing import Annotated

from fastapi import Depends, Request

from ..queue.tasks import Queue
from .context import Context


def get_context(request: Request) -> Context:
    return request.app.state.ctx


def get_queue(request: Request) -> Queue:
    return request.app.state.queue


ContextDep = Annotated[Context, Depends(get_context)]
QueueDep = Annotated[Queue, Depends(get_queue)]
