"""benchmarks/measure/keyed.py, the benchmarks' one cache of a model's scores: a score is reused only for the
model bytes and the test frames it was made for. (finetune_guard once read back a zero-shot made on a model's
earlier held-out frames; ship_mix and ship_geometry keyed their baselines by the model's path, so a model
retrained or shipped again under the same path kept its predecessor's scores.)"""
from __future__ import annotations

from benchmarks.measure import keyed
from benchmarks.what_a_user_gets import finetune_guard as guard


def _model(tmp_path, data=b"weights one"):
    model = tmp_path / "road-all" / "road.pt"
    model.parent.mkdir(exist_ok=True)
    model.write_bytes(data)
    return model


def test_a_cached_score_is_reused_only_for_its_model_and_test_frames(tmp_path):
    model = _model(tmp_path)
    items = [("a.jpg", "a.png", "000100_10"), ("b.jpg", "b.png", "000101_10")]
    key = guard.cache_key(model, items)
    assert guard.cached(tmp_path / "zero.json", key) is None  # nothing yet
    guard.store(tmp_path / "zero.json", key, {"iou": 84.0})
    assert guard.cached(tmp_path / "zero.json", key) == {"iou": 84.0}
    assert guard.cached(tmp_path / "zero.json", guard.cache_key(model, items[:1])) is None  # other test frames
    model.write_bytes(b"weights two")
    assert guard.cached(tmp_path / "zero.json", guard.cache_key(model, items)) is None  # another model, same folder
    (tmp_path / "old.json").write_text('{"iou": 86.6}')  # a score without its key (an earlier run's): not trusted
    assert guard.cached(tmp_path / "old.json", key) is None


def test_a_baseline_on_a_store_is_scored_again_when_the_model_or_the_store_changes(tmp_path):
    store = tmp_path / "store"
    store.mkdir()
    (store / "manifest.jsonl").write_text('{"id": "a"}\n{"id": "b"}\n')
    model, cache, calls = _model(tmp_path), tmp_path / "shipped" / "result-camvid.json", []

    def score():
        calls.append(1)
        return {"iou": 0.9 + len(calls) / 100}

    first = keyed.scored(cache, keyed.store_key(model, store), score)
    assert keyed.scored(cache, keyed.store_key(model, store), score) == first and len(calls) == 1  # read back
    model.write_bytes(b"weights retrained")  # same path, other bytes
    assert keyed.scored(cache, keyed.store_key(model, store), score) != first and len(calls) == 2
    (store / "manifest.jsonl").write_text('{"id": "a"}\n')  # the store rebuilt on other frames
    keyed.scored(cache, keyed.store_key(model, store), score)
    assert len(calls) == 3
    assert keyed.digest(model) == __import__("hashlib").sha256(b"weights retrained").hexdigest()[:16]


def test_a_workdir_cleaned_of_its_stores_keeps_the_scores_cached_for_the_same_model(tmp_path):
    store = tmp_path / "store"
    store.mkdir()
    (store / "manifest.jsonl").write_text('{"id": "a"}\n')
    model, cache = _model(tmp_path), tmp_path / "shipped" / "result-bdd.json"
    assert keyed.scored_on_store(cache, model, store, lambda: {"iou": 0.7}) == {"iou": 0.7}
    (store / "manifest.jsonl").unlink()
    store.rmdir()  # the stores deleted, the cache kept
    assert keyed.scored_on_store(cache, model, store, lambda: {"iou": 0.1}) == {"iou": 0.7}  # nothing to score on
    model.write_bytes(b"weights two")
    assert keyed.scored_on_store(cache, model, store, lambda: {"iou": 0.1}) is None  # another model's score: none
