"""benchmarks/what_a_user_gets/finetune_guard.py's cache: a score is reused only for the model bytes and the
test frames it was made for. (A folder scored once with a model's earlier held-out frames, or with another
model under the same folder name, was read back as if it were this run's.)"""
from __future__ import annotations

from benchmarks.what_a_user_gets import finetune_guard as guard


def test_a_cached_score_is_reused_only_for_its_model_and_test_frames(tmp_path):
    model = tmp_path / "road-all" / "road.pt"
    model.parent.mkdir()
    model.write_bytes(b"weights one")
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
