"""The fabric library: embed a dataset once, then match photos, depth maps or GelSight presses.

    >>> from lookfeel import Modality
    >>> from lookfeel.index import Library, Matcher, build_library
    >>> build_library("run/checkpoints/best.pt", "my_fabrics/", "lib/")
    >>> matcher = Matcher(Library.open("lib/"))
    >>> [result] = matcher.match_files(["press1.png", "press2.png"], Modality.TOUCH)
    >>> result.known, result.fabrics[0].fabric_id, result.fabrics[0].probability

Modules: `build` (resumable, sharded embedding), `library` (the folder format, reading it),
`calibrate` (c of ``exp(-c D^2)`` and the "unknown" threshold, leave fabrics out), `search`
(exact numpy or faiss HNSW), `query` (reading query images as training does), `match`
(ranking fabrics, nearest items per modality, property estimates).
"""

from lookfeel.index.build import BuildResult, build_library
from lookfeel.index.calibrate import Calibration, PairCalibration, calibrate, calibrate_pair
from lookfeel.index.library import (
    FabricRecord,
    Library,
    LibraryError,
    LibraryItem,
    ModalityTable,
)
from lookfeel.index.match import (
    FabricMatch,
    ItemRef,
    Matcher,
    MatchFailure,
    MatchResult,
    PropertyEstimate,
    format_match,
)
from lookfeel.index.query import load_query_bytes, load_query_image, query_batch, sniff_type
from lookfeel.index.search import (
    AUTO_FAISS_MIN_ROWS,
    BACKENDS,
    ExactSearch,
    FaissSearch,
    choose_backend,
)

__all__ = [
    "AUTO_FAISS_MIN_ROWS",
    "BACKENDS",
    "BuildResult",
    "Calibration",
    "ExactSearch",
    "FabricMatch",
    "FabricRecord",
    "FaissSearch",
    "ItemRef",
    "Library",
    "LibraryError",
    "LibraryItem",
    "MatchFailure",
    "MatchResult",
    "Matcher",
    "ModalityTable",
    "PairCalibration",
    "PropertyEstimate",
    "build_library",
    "calibrate",
    "calibrate_pair",
    "choose_backend",
    "format_match",
    "load_query_bytes",
    "load_query_image",
    "query_batch",
    "sniff_type",
]
