"""The models of a study: training images/s against a pure training step of the same shape
(:func:`reference_images_per_s`), :func:`convergence`, and one seed's rows and model records
(:func:`collect_seed`).
"""
from __future__ import annotations

import hashlib
import json
import time
from pathlib import Path


def reference_images_per_s(ck: dict, threads: int, seconds: float, min_steps: int) -> float:
    """Images/s of a pure training step (forward, cross-entropy, backward, optimiser step) on random
    tensors shaped like the checkpoint's training batches: the same model args, batch, working size,
    memory format, optimiser and device as ``vctrain fit`` used, no data loading."""
    import torch
    from torch.nn import functional as F

    from vctrain.networks import build_model
    from vctrain.training import resolve_device

    torch.set_num_threads(threads)
    cfg, margs = ck["config"], ck["model_args"]
    device = resolve_device(cfg.get("device") or "auto")
    w, h = ck["data"].get("crop_size") or ck["data"]["input_size"]  # the training batches' shape
    batch = int(cfg.get("batch_size") or 8)
    fmt = torch.channels_last if margs["arch"] == "resfpn" else torch.contiguous_format
    torch.manual_seed(0)
    model = build_model(margs).to(device, memory_format=fmt).train()
    lr, wd, mom = cfg.get("lr") or 1e-3, cfg.get("weight_decay") or 0.0, cfg.get("momentum") or 0.9
    if cfg.get("optimizer") == "adamw":
        opt = torch.optim.AdamW(model.parameters(), lr=lr, betas=(mom, 0.999), weight_decay=wd)
    else:
        opt = torch.optim.SGD(model.parameters(), lr=lr, momentum=mom, weight_decay=wd)
    x = torch.randn(batch, margs["in_channels"], h, w, device=device).contiguous(memory_format=fmt)
    y = torch.randint(0, margs["num_classes"], (batch, h, w), device=device)

    def step() -> None:
        loss = F.cross_entropy(model(x), y, ignore_index=255)
        opt.zero_grad(set_to_none=True)
        loss.backward()
        opt.step()

    for _ in range(2):  # warm-up (allocator, kernels)
        step()
    n, t0 = 0, time.perf_counter()
    while n < min_steps or time.perf_counter() - t0 < seconds:
        step()
        n += 1
    if device.type == "cuda":
        torch.cuda.synchronize()
    return batch * n / (time.perf_counter() - t0)


def convergence(log: list[dict], epochs: int, best_epoch: int) -> tuple[bool, str]:
    """Converged: the best epoch is not the last, or the validation IoU plateaued (the last quarter
    of the epochs, at least 2, improves the best before it by < 0.5 IoU points)."""
    if 0 < best_epoch < epochs:
        return True, f"best epoch {best_epoch} of {epochs}"
    vals = [r["val_iou"] for r in log if "val_iou" in r]
    k = max(2, len(vals) // 4)
    if len(vals) < k + 2:
        return False, f"best epoch is the last of {epochs}; too few epochs to see a plateau"
    gain = max(vals[-k:]) - max(vals[:-k])
    if gain < 0.005:
        return True, f"plateau: the last {k} epochs gain {100 * gain:.2f} IoU points"
    return False, f"still improving: the last {k} epochs gain {100 * gain:.2f} IoU points"


def collect_seed(sd: Path, conditions: list[str], threads: int, quick: bool) -> tuple[dict, list[dict]]:
    """{(test set, condition): row} and one record per model (timings, convergence, pipeline ratio)."""
    import torch

    rows = {(r["heldout"], r["condition"]): r
            for r in map(json.loads, (sd / "results.jsonl").read_text().splitlines())}
    models, refs = [], {}
    for c in conditions:
        run_dir = sd / "runs" / "_all" / c
        if not (run_dir / "train.json").exists():
            continue
        tj = json.loads((run_dir / "train.json").read_text())
        ck = torch.load(run_dir / "model.pt", map_location="cpu", weights_only=False)
        log = [json.loads(line) for line in (run_dir / "model.log.jsonl").read_text().splitlines()]
        shape = json.dumps([ck["model_args"], ck["data"].get("crop_size") or ck["data"]["input_size"],
                            ck["config"].get("batch_size"),
                            ck["config"].get("optimizer"), ck["config"].get("device"), threads], sort_keys=True)
        # the reference is measured right after the training it belongs to and kept with it, so a
        # resumed benchmark reuses it; one per distinct shape (resize and virtual share the working size)
        cache = run_dir / "reference.json"
        key = hashlib.sha256(((run_dir / "train.json").read_text() + shape).encode()).hexdigest()[:16]
        old = json.loads(cache.read_text()) if cache.exists() else {}
        if old.get("key") == key:
            ref = old["images_per_s"]
        else:
            if shape not in refs:
                refs[shape] = reference_images_per_s(ck, threads, 2.0 if quick else 20.0, 3 if quick else 10)
            ref = refs[shape]
            cache.write_text(json.dumps({"key": key, "images_per_s": ref}) + "\n")
        ok, why = convergence(log, tj["epochs"], tj["best_epoch"])
        models.append({"condition": c, "train_minutes": tj["train_seconds"] / 60, "epochs": tj["epochs"],
                       "best_epoch": tj["best_epoch"], "best_val_iou": tj["best_val_iou"],
                       "train_items": tj["train_items"], "val_items": tj["val_items"],
                       "input_size": tj["input_size"], "crop_size": ck["data"].get("crop_size"),
                       "model_args": ck["model_args"],
                       "batch_size": ck["config"].get("batch_size"), "optimizer": ck["config"].get("optimizer"),
                       "train_images_per_s": tj["train_images_per_s"], "reference_images_per_s": ref,
                       "pipeline_ratio": tj["train_images_per_s"] / ref, "converged": ok,
                       "convergence": why, "val_iou_per_epoch": [r.get("val_iou") for r in log]})
    return rows, models
