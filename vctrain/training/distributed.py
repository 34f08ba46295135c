"""Multi-process training under torchrun (DistributedDataParallel): the process group's rank and size,
BatchNorm statistics averaged over processes, and a clean end of the group (:func:`leave_group`)."""
from __future__ import annotations

import gc
import os

import torch
from torch import nn

__all__ = ["ranks", "average_buffers", "import_before_group", "replicas_identical", "leave_group"]


def ranks() -> tuple[int, int, int]:
    """(rank, world size, local rank) from torchrun's environment."""
    return int(os.environ.get("RANK", 0)), int(os.environ.get("WORLD_SIZE", 1)), int(os.environ.get("LOCAL_RANK", 0))


def average_buffers(model: nn.Module, world: int) -> None:
    """Average BatchNorm running statistics over processes (DDP syncs gradients, not these;
    SyncBatchNorm needs GPUs), so every replica evaluates and saves the same model."""
    for b in model.buffers():
        if b.is_floating_point():
            torch.distributed.all_reduce(b, op=torch.distributed.ReduceOp.SUM)
            b.div_(world)


def import_before_group() -> None:
    """Import ``torch.distributed.nn.functional`` before the process group exists. Its functions
    take ``group=group.WORLD`` as a default argument, bound when the module is first imported;
    the optimiser imports it (through torch._dynamo) on first use, and imported after
    init_process_group it holds the group for good: destroy_process_group then leaves gloo's
    threads running, and about 1 exit in 40 aborted ("terminate called without an active
    exception", SIGABRT; torch 2.13)."""
    import torch.distributed.nn.functional  # noqa: F401


def leave_group(loop, model: nn.Module, world: int) -> bool:
    """The end of a multi-process run: the DDP wrapper dropped and collected (it sits in a
    reference cycle that holds the process group, so that destroy_process_group ends gloo's
    threads here, not at interpreter exit); then :func:`replicas_identical`."""
    loop.net = model
    gc.collect()
    return replicas_identical(model, world)


def replicas_identical(model: nn.Module, world: int) -> bool:
    """Whether every process ends with the same weights (DDP keeps them in lockstep); then the
    process group is torn down."""
    flat = torch.cat([t.detach().float().reshape(-1) for t in model.state_dict().values()])
    copies = [torch.empty_like(flat) for _ in range(world)]
    torch.distributed.all_gather(copies, flat)
    same = all(torch.equal(copies[0], c) for c in copies[1:])
    torch.distributed.barrier()
    # tear the process group down here, not at interpreter exit, where gloo's threads can
    # abort the process ("terminate called without an active exception")
    torch.distributed.destroy_process_group()
    return same
