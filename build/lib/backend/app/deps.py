"""Dependencies as Annotated aliases: handlers declare what they need by type.

They are ``async def`` although they never await: FastAPI runs a plain ``def`` dependency in its
thread pool, and a thread hop per dependency per request was most of a status read's cost (and its
latency once the cores are busy). Nothing here blocks, so it runs on the event loop."""
from __future__ import annotations

from typing import Annotated

from fastapi import Depends, Request

from ..base.context import Context
from ..queue.tasks import Queue


async def get_context(request: Request) -> Context:
    return request.app.state.ctx


async def get_queue(request: Request) -> Queue:
    return request.app.state.queue


ContextDep = Annotated[Context, Depends(get_context)]
QueueDep = Annotated[Queue, Depends(get_queue)]
