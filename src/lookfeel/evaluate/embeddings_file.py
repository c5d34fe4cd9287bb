"""The embeddings file of ``lookfeel embed``: per-modality arrays in one ``.npz``, and back.

Arrays, for each modality ``<m>`` (``depth``, ``color``, ``touch``):

- ``embeddings_<m>``: (N, D) float32, one row per item (touch: per press);
- ``fabric_id_<m>``: (N,) int64;
- ``path_<m>``: (N,) str, the item's file (a press's first frame);
- ``reference_embeddings_<m>``, ``reference_fabric_id_<m>``, ``reference_path_<m>``: the same
  for the reference (training) fabrics, when written, so that c and the property probes can be
  fitted from the file alone;
- ``meta``: a 0-d str array holding JSON: ``format``, ``split``, ``split_description``,
  ``checkpoint``, ``step``, ``data_root``, ``data_config`` (the run's preprocessing),
  ``presses`` (the run's presses per touch input) and ``pool_exact`` (whether max-pooling
  final embeddings equals the model's own multi-press pooling).

Plain arrays, no pickles: read it with ``np.load(path)`` from any language with an npz reader.
"""

from __future__ import annotations

import json
import os
import zipfile
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from lookfeel.atomic import atomic_write
from lookfeel.data import Catalog, Item
from lookfeel.embedding import EmbeddedItems
from lookfeel.errors import LookfeelError, load_problem
from lookfeel.modality import Modality

__all__ = [
    "EMBEDDINGS_FORMAT",
    "EmbeddingFileError",
    "EmbeddingSet",
    "embedded_from_arrays",
    "load_embeddings",
    "save_embeddings",
]

EMBEDDINGS_FORMAT = 1
"""Version of the npz layout; a newer file is refused with a clear message."""


class EmbeddingFileError(LookfeelError):
    """An embeddings file cannot be read; the message names the file."""


@dataclass(frozen=True)
class EmbeddingSet:
    """Embeddings of the test items, optionally of reference (training) fabrics, and provenance.

    Attributes:
        embedded: the items to evaluate, per modality.
        reference: the reference fabrics' items (c and probes are fitted on them), or None.
        meta: provenance (see the module docstring).
    """

    embedded: dict[Modality, EmbeddedItems]
    reference: dict[Modality, EmbeddedItems] | None = None
    meta: dict[str, Any] = field(default_factory=dict)


def embedded_from_arrays(
    embeddings: Mapping[Modality, ArrayLike] | Mapping[str, ArrayLike],
    fabric_ids: Mapping[Modality, ArrayLike] | Mapping[str, ArrayLike],
    paths: Mapping[Modality, Sequence[str]] | Mapping[str, Sequence[str]] | None = None,
    catalog: Catalog | None = None,
) -> dict[Modality, EmbeddedItems]:
    """Wrap plain arrays (any model's, a baseline's, a user's) for `evaluate_embeddings`.

    Args:
        embeddings: modality -> (N, D) embeddings.
        fabric_ids: modality -> (N,) fabric ids.
        paths: modality -> N file paths (for example figures); default: none.
        catalog: when given, each path is matched (by modality and file name) to the
            catalog's item, so its press frames and kind are known.

    Raises:
        ValueError: mismatched lengths or modalities.
    """
    emb = {Modality(k): np.asarray(v, dtype=np.float32) for k, v in embeddings.items()}
    fab = {Modality(k): np.asarray(v, dtype=np.int64).reshape(-1) for k, v in fabric_ids.items()}
    if set(emb) != set(fab):
        raise ValueError(
            f"embeddings and fabric ids name different modalities: {sorted(emb)} vs {sorted(fab)}"
        )
    pth = {Modality(k): list(v) for k, v in (paths or {}).items()}
    known: dict[tuple[Modality, str], Item] = {}
    if catalog is not None:
        for m in catalog.modalities:
            for it in catalog.items(m):
                known[(m, it.path.name)] = it
    out = {}
    for m in emb:
        e, f = emb[m], fab[m]
        if e.ndim != 2 or len(e) != len(f):
            raise ValueError(f"{m.value}: embeddings {e.shape} do not fit {len(f)} fabric ids")
        ps = pth.get(m, [f"{m.value}_{i}" for i in range(len(f))])
        if len(ps) != len(f):
            raise ValueError(f"{m.value}: {len(ps)} paths for {len(f)} embeddings")
        items = tuple(
            known.get((m, Path(p).name)) or Item(m, int(fid), (Path(p),))
            for p, fid in zip(ps, f.tolist(), strict=True)
        )
        out[m] = EmbeddedItems(m, e, f, items)
    return out


def _arrays(prefix: str, embedded: Mapping[Modality, EmbeddedItems]) -> dict[str, np.ndarray]:
    out: dict[str, np.ndarray] = {}
    for m, e in embedded.items():
        out[f"{prefix}embeddings_{m.value}"] = np.asarray(e.embeddings, dtype=np.float32)
        out[f"{prefix}fabric_id_{m.value}"] = np.asarray(e.fabric_ids, dtype=np.int64)
        out[f"{prefix}path_{m.value}"] = np.array(e.paths, dtype=np.str_).reshape(len(e.paths))
    return out


def save_embeddings(path: str | os.PathLike[str], embeddings: EmbeddingSet) -> Path:
    """Write an `EmbeddingSet` as an npz file, atomically (see the module docstring).

    Returns:
        The path written.
    """
    arrays = _arrays("", embeddings.embedded)
    if embeddings.reference is not None:
        arrays |= _arrays("reference_", embeddings.reference)
    meta = {"format": EMBEDDINGS_FORMAT, **embeddings.meta}
    arrays["meta"] = np.array(json.dumps(meta, sort_keys=True))
    return atomic_write(path, lambda f: np.savez(f, **arrays))  # type: ignore[arg-type]


def _group(
    data: Mapping[str, np.ndarray], prefix: str, catalog: Catalog | None, where: Path
) -> dict[Modality, EmbeddedItems]:
    emb, fab, paths = {}, {}, {}
    for m in Modality:
        key = f"{prefix}embeddings_{m.value}"
        if key not in data:
            continue
        fkey = f"{prefix}fabric_id_{m.value}"
        if fkey not in data:
            raise EmbeddingFileError(f"{where}: has {key} but no {fkey}")
        emb[m], fab[m] = data[key], data[fkey]
        if np.issubdtype(emb[m].dtype, np.number) and not np.isfinite(emb[m]).all():
            rows = int((~np.isfinite(emb[m].reshape(len(emb[m]), -1))).any(axis=1).sum())
            raise EmbeddingFileError(
                f"{where}: {key} holds NaN or infinity in {rows} of {len(emb[m])} rows: the "
                "model that embedded them diverged or the file is damaged"
            )
        pkey = f"{prefix}path_{m.value}"
        if pkey in data:
            paths[m] = [str(p) for p in data[pkey].tolist()]
    try:
        return embedded_from_arrays(emb, fab, paths, catalog)
    except ValueError as e:
        raise EmbeddingFileError(f"{where}: {e}") from None


def load_embeddings(path: str | os.PathLike[str], catalog: Catalog | None = None) -> EmbeddingSet:
    """Read an embeddings file written by `save_embeddings` (or by hand, with the same keys).

    Args:
        path: the npz file.
        catalog: the dataset, to recover each row's item (frames, press kind) by file name.

    Raises:
        EmbeddingFileError: missing, unreadable, of a newer format, or without embeddings.
    """
    p = Path(path)
    if not p.is_file():
        raise EmbeddingFileError(f"{p}: embeddings file not found")
    try:
        with np.load(p, allow_pickle=False) as z:
            data = {k: z[k] for k in z.files}
    except (OSError, ValueError, zipfile.BadZipFile) as e:
        raise EmbeddingFileError(f"{p}: not a readable npz file ({load_problem(e)})") from None
    meta: dict[str, Any] = {}
    if "meta" in data:
        try:
            meta = json.loads(str(data["meta"]))
        except json.JSONDecodeError:
            raise EmbeddingFileError(f"{p}: its meta entry is not JSON") from None
    if int(meta.get("format", EMBEDDINGS_FORMAT)) > EMBEDDINGS_FORMAT:
        raise EmbeddingFileError(
            f"{p}: written by a newer lookfeel (format {meta['format']}); upgrade"
        )
    embedded = _group(data, "", catalog, p)
    if not embedded:
        raise EmbeddingFileError(
            f"{p}: no embeddings_<modality> array (have: {', '.join(sorted(data)) or 'none'})"
        )
    reference = _group(data, "reference_", catalog, p) or None
    return EmbeddingSet(embedded, reference, meta)
