"""HEAD wherever GET is served, as HTTP asks (FastAPI's routes answer it 405): the request is
routed as a GET and only the response's head is sent. A response that knows it was asked for its
head alone (a file, an event stream) does no work for the body."""

from __future__ import annotations

from typing import Any

from starlette.types import ASGIApp, Message, Receive, Scope, Send

HEAD_ONLY = "slrig.head_only"  # in the scope of a HEAD routed as GET


def head_only(scope: Any) -> bool:
    """The request was a HEAD: send the head of the response, no body."""
    return bool(scope.get(HEAD_ONLY))


class HeadAsGet:
    def __init__(self, app: ASGIApp) -> None:
        self.app = app

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if scope["type"] != "http" or scope["method"] != "HEAD":
            await self.app(scope, receive, send)
            return
        finished = False

        async def head_alone(message: Message) -> None:
            nonlocal finished
            if finished:
                return  # the rest of a body nobody asked for
            if message["type"] == "http.response.body":
                finished = True
                message = {"type": "http.response.body", "body": b"", "more_body": False}
            await send(message)

        async def gone_once_answered() -> Message:
            if finished:  # a stream still running ends as if its client had gone
                return {"type": "http.disconnect"}
            return await receive()

        await self.app({**scope, "method": "GET", HEAD_ONLY: True}, gone_once_answered, head_alone)
