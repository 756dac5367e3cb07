"""The dataset stage: build a :class:`Capture` (displacements, neutral, hand basis) from a dataset config.

The registry of builders (``dataset.kind``) and :func:`build_captures`; the builders live in their own modules
(:mod:`~workbench.dataset.synthetic_builder`, :mod:`~workbench.dataset.animface`, ...) and share
:mod:`workbench.dataset.common`."""

from __future__ import annotations

from dataclasses import replace
from typing import Mapping

from workbench.dataset.animface import build_animface
from workbench.dataset.cache import cached_captures, dataset_key
from workbench.dataset.capture import Capture
from workbench.dataset.hand_basis import apply_hand_basis
from workbench.dataset.ict_livelink import build_ict_livelink
from workbench.dataset.mesh_sequence import build_mesh_sequence
from workbench.dataset.real import data_file_checksums
from workbench.dataset.storage import FrameStorage, frame_storage
from workbench.dataset.synthetic_builder import build_synthetic
from workbench.settings.typed import built_settings, dataset_settings

BUILDERS = {
    "synthetic": build_synthetic,
    "ict_livelink": build_ict_livelink,
    "animface": build_animface,
    "mesh_sequence": build_mesh_sequence,
}
"""``dataset.kind`` -> builder taking the typed ``dataset`` settings and the :class:`FrameStorage` its dense frames
are written into, returning ``{train_on name: Capture}``."""


def build_captures(cfg: Mapping, cache_dir: str | None = None) -> dict[str, Capture]:
    """Build the captures a dataset config describes, one per ``dataset.train_on`` name.

    The same config (and dataset code and source files) gives the captures built before: from memory within a
    process, from ``cache_dir`` across processes when it is set (:mod:`workbench.dataset.cache`).

    Parameters
    ----------
    cfg : typed dataset settings or mapping
        The ``dataset`` group (:func:`workbench.settings.typed.dataset_settings` types a mapping; the API's
        :func:`workbench.api.build_captures` checks it first); ``kind`` selects the builder.
    cache_dir : str, optional
        Folder of the disk cache (``paths.cache_dir``); memory only when None. Frames stored on disk
        (``dataset.storage: disk``) are kept in its ``frames`` folder.

    Returns
    -------
    dict
        ``train_on`` name -> :class:`Capture`, in the configured order; with ``dataset.hand_basis`` set, their
        hand shapes read from that file (:mod:`workbench.dataset.hand_basis`).
    """
    return build_from_settings(dataset_settings(cfg), cache_dir)


def build_from_settings(dataset, cache_dir: str | None = None) -> dict[str, Capture]:
    """:func:`build_captures` of typed dataset settings (:func:`workbench.settings.typed.dataset_settings`), as the
    study passes them: taken as they are, neither typed nor checked again."""
    storage = frame_storage(dataset.storage, dataset.dtype, cache_dir)
    keyed, key_settings = built_settings(dataset)  # the hand-basis file is read outside the cache, after the build

    def build(values: Mapping):
        captures = BUILDERS[keyed.kind](keyed, storage)
        files = data_file_checksums(values)  # what the run read, for its provenance
        return {
            name: stored_frames(
                replace(capture, provenance={**capture.provenance, "data_files": files}) if files else capture,
                storage,
                (dataset_key(values), name),
            )
            for name, capture in captures.items()
        }

    captures, spec = cached_captures(key_settings, build, cache_dir), dataset.hand_basis
    if spec is None:
        return dict(captures)
    return apply_hand_basis(
        captures,
        spec.path,
        spec.shapes,
        data_root=getattr(dataset, "data_root", None),  # the synthetic actor has none
        neutral=spec.neutral,
        unit_mm=spec.unit_mm,
        mesh=spec.mesh,
        region_vertices=spec.region_vertices,
    )


def stored_frames(capture: Capture, storage: FrameStorage, key) -> Capture:
    """The capture with its training and evaluated frames kept as ``storage`` says (the same frames once when
    they are the same, ``split: same``); frames a builder wrote into ``storage`` are kept as they are."""
    train = storage.keep("train", key, capture.train)
    evaluate = train if capture.eval is capture.train else storage.keep("eval", key, capture.eval)
    return replace(capture, train=train, eval=evaluate)
