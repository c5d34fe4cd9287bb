"""``lookfeel serve``: a web page and a JSON API that match images against a library.

Serve a page and a JSON API (OpenAPI at /openapi.json) over a library. A library rebuilt
while it runs (`lookfeel index build` into the same folder) is served once it is loaded; until
then, and when a rebuild cannot be served (said in one line), the one opened before answers.
The server has no login: on an address other than loopback (--host 0.0.0.0) anyone who can
reach this machine can use it, which is warned of in one line.
"""

from __future__ import annotations

import argparse
import sys

from lookfeel.cli._args import Subparsers, add_command, add_device, add_library


def add_parser(subparsers: Subparsers) -> None:
    """Register ``serve``."""
    sv = add_command(subparsers, "serve", __doc__, run)
    add_library(sv)
    sv.add_argument(
        "--host", default="127.0.0.1", help="address (default 127.0.0.1: this machine only)"
    )
    sv.add_argument("--port", type=int, default=8000, help="port (default 8000)")
    sv.add_argument(
        "--max-upload-mb", type=float, default=8.0, help="largest upload in MB (default 8)"
    )
    sv.add_argument(
        "--max-concurrency",
        type=int,
        default=2,
        help="queries the model runs at once (default 2)",
    )
    sv.add_argument("--threads", type=int, default=1, help="PyTorch threads per query (default 1)")
    add_device(sv)
    sv.add_argument(
        "--max-megapixels",
        type=float,
        default=25.0,
        help="largest upload in megapixels, width x height from its header, checked before "
        "decoding (default 25)",
    )


def run(args: argparse.Namespace) -> int:
    """Open the library and serve it until interrupted."""
    import torch

    from lookfeel.devices import resolve_device
    from lookfeel.index import Library
    from lookfeel.serve import ServeOptions, create_app, serve
    from lookfeel.serve.server import is_loopback, is_unspecified

    # Every option is checked in one place, before anything is loaded.
    options = ServeOptions(
        host=args.host,
        port=args.port,
        threads=args.threads,
        max_upload_mb=args.max_upload_mb,
        max_concurrency=args.max_concurrency,
        max_megapixels=args.max_megapixels,
    )
    device = resolve_device(args.device)  # a device this machine lacks: one line
    # Queries run side by side, each on few threads: on a busy CPU one OpenMP team per query
    # beats several queries sharing two-thread teams that spin waiting for each other.
    torch.set_num_threads(options.threads)
    library = Library.open(args.index, checkpoint=args.checkpoint)
    app = create_app(library, options.config(), device=device)

    def serving(url: str) -> None:  # said once the address is bound, never of one in use
        if not is_loopback(options.host):
            print(
                f"lookfeel: warning: --host {options.host}: the demo is reachable from other "
                "machines and has no authentication: anyone who can reach this one can upload "
                "images and read the library; leave --host out (127.0.0.1) to keep it to this "
                "machine",
                file=sys.stderr,
                flush=True,
            )
        elsewhere = (
            " from this machine; other machines use this machine's address"
            if is_unspecified(options.host)
            else ""
        )
        print(f"Serving {args.index} at {url}{elsewhere} (Ctrl-C stops)", flush=True)

    serve(app, host=options.host, port=options.port, on_bound=serving)
    return 0
