"""The operator's station: run, watch and answer a procedure from a browser (``aatest station``).

Modules (data flows from the browser to the engine and back):

- ``security``   loopback by default, a ≥ 32-character token otherwise, same-origin only
- ``catalogue``  procedures by id (shipped and lab), validation, run history and run files
- ``live``       the run's events as JSON for the page; prompts answered from the page
- ``control``    one run at a time in a worker thread: start, resume, answer, abort
- ``app``        the Starlette application: page, JSON API, the websocket
- ``serve``      ``aatest station``: option checks, then uvicorn
- ``static/``    the page (HTML, JS, CSS, no build step) and the vendored uPlot
"""

from aatest.station.serve import StationOptions, build, serve

__all__ = ["StationOptions", "build", "serve"]
