"""Where the lab's caches live and how pickles written before the move are read: an older
checkout's corpus in bench/.cache is used until lab/.cache/corpus exists, and a pickle naming
a class at its old place (bench._corpus_plan.TepRun, ...) loads as today's class."""

from __future__ import annotations

import importlib
import pickle

import numpy as np
import pytest

from lab import _cache
from lab._types import Window
from lab.sources.tep_plan import TepRun


@pytest.fixture
def places(tmp_path, monkeypatch):
    here, before = tmp_path / "lab" / ".cache", tmp_path / "bench" / ".cache"
    monkeypatch.setattr(_cache, "HERE", here)
    monkeypatch.setattr(_cache, "BEFORE", before)
    return here, before


def test_the_cache_is_the_labs_unless_an_older_corpus_is_found(places) -> None:
    here, before = places
    assert _cache.corpus() == here / "corpus"  # nothing built anywhere
    (before / "corpus").mkdir(parents=True)
    assert _cache.root() == before and _cache.corpus() == before / "corpus"
    (here / "corpus").mkdir(parents=True)  # moved, or built anew: the lab's own wins
    assert _cache.corpus() == here / "corpus"


def _as_before_the_move(obj: object, old: str) -> bytes:
    """``obj`` pickled as a checkout before the move wrote it: its class at module ``old``."""
    cls = type(obj)
    text = pickle.dumps(obj, protocol=0)
    new = f"c{cls.__module__}\n{cls.__qualname__}\n".encode()
    assert new in text
    return text.replace(new, f"c{old}\n{cls.__qualname__}\n".encode())


def test_pickles_of_moved_classes_load_as_todays(tmp_path) -> None:
    run = TepRun("mode2", 7, ((11, 1.0),), ((14, 2.0),))
    window = Window("plant", "plant-tag", "FIC1", "flow", "stiction", True, np.arange(3.0),
                    np.ones(3), 1.0, "self-regulating", "", float("nan"))
    for obj, old in ((run, "bench._corpus_plan"), (window, "bench._corpus_types")):
        data = _as_before_the_move(obj, old)
        with pytest.raises(ModuleNotFoundError):
            pickle.loads(data)
        path = tmp_path / "old.pickle"
        path.write_bytes(data)
        got = _cache.load(path)
        assert type(got) is type(obj)
        assert pickle.dumps(got, protocol=0) == pickle.dumps(obj, protocol=0)  # every field


def test_every_moved_class_is_where_the_map_says() -> None:
    for (old, name), new in _cache.MOVED.items():
        assert old.startswith("bench.") and new.startswith("lab.")
        assert isinstance(getattr(importlib.import_module(new), name), type), (old, name)


def test_dump_writes_through_a_temporary_file(tmp_path) -> None:
    path = tmp_path / "deep" / "x.pickle"
    _cache.dump({"a": 1}, path)
    assert _cache.load(path) == {"a": 1} and not path.with_suffix(".tmp").exists()
