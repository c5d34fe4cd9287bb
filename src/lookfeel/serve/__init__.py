"""The web app over a fabric library: a page and a JSON API (FastAPI).

    >>> from lookfeel.serve import create_app, serve
    >>> serve(create_app("lib/"), host="127.0.0.1", port=8000)

or ``lookfeel serve --index lib/``.
"""

from lookfeel.serve.app import ServeConfig, ServeOptionError, ServeOptions, create_app
from lookfeel.serve.server import background_server, serve

__all__ = [
    "ServeConfig",
    "ServeOptionError",
    "ServeOptions",
    "background_server",
    "create_app",
    "serve",
]
