"""The station's ``/fleet`` page: control charts and fleet diagnosis from its records store.

Rendered on request in a worker thread (the store is queried and the template rendered in the
report sandbox's confined child), served as a document with the report policy: no script runs
in it, nothing is fetched. Simulations are left out, as everywhere a history is shown.
"""

from __future__ import annotations

import asyncio

from starlette.requests import Request
from starlette.responses import HTMLResponse, Response

from aatest.engine.errors import AatestError

#: the longest model name the page's ``?model=`` accepts (model names are a few characters)
_MAX_MODEL = 64


async def fleet_page(request: Request, records_url: str | None, policy: str) -> Response:
    """The fleet page of ``records_url`` (404 without a store; ``?model=`` narrows it)."""
    from aatest.fleet.commands import Selection, overview_page

    if records_url is None:
        return Response("the station has no records store (start it with --records)",
                        status_code=404)
    model = request.query_params.get("model") or None
    if model is not None and len(model) > _MAX_MODEL:
        return Response("model name too long", status_code=400)
    try:
        html = await asyncio.to_thread(overview_page, Selection(records_url, model))
    except AatestError as exc:
        return Response(f"fleet page unavailable: {exc}", status_code=503)
    return HTMLResponse(html, headers={"content-security-policy": policy})
