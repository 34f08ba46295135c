"""The models that ship with the repository (``models/<name>/*.pt``), reachable by name from any
folder: :func:`resolve_model` is what ``vctrain predict``, ``vctrain export`` and :func:`vctrain.load`
take as a model ('shipped' names the one the README and ``make demo`` use). No torch here: the
commands start without it."""
from __future__ import annotations

from pathlib import Path

from vcprep.errors import InputError, one_of

__all__ = ["MODELS", "SHIPPED", "shipped_models", "resolve_model"]

MODELS = Path(__file__).resolve().parents[1] / "models"
# the model `shipped` names (issue 82: chosen on cameras held out of training, all six datasets); the
# ones shipped before, road-street and road-multicamera, stay reachable by their names (their cards)
SHIPPED = "road-all"


def shipped_models() -> dict[str, Path]:
    """name -> model file of every model under :data:`MODELS` ('shipped' first: :data:`SHIPPED`'s)."""
    found = {d.name: sorted(d.glob("*.pt"))[0] for d in sorted(MODELS.glob("*")) if any(d.glob("*.pt"))}
    return {"shipped": found[SHIPPED], **found} if SHIPPED in found else found


def resolve_model(arg: str | Path | None) -> Path | None:
    """A model as given: a file that exists as given; else a shipped model's name ('shipped', 'road-all',
    'road-street', 'road-multicamera'; :func:`shipped_models`); a missing .pt/.onnx file or unknown name is
    refused naming the shipped model's path and its names (anything else is left to the loader)."""
    if arg is None:
        return None
    arg = Path(arg)
    if arg.exists():
        return arg
    models = shipped_models()
    if str(arg) in models:
        return models[str(arg)]
    if not models or arg.suffix.lower() not in ("", ".pt", ".onnx"):
        return arg
    here = f"the shipped model is {models['shipped']}, named {SHIPPED} or shipped; " if "shipped" in models else ""
    what = "ONNX graph" if arg.suffix.lower() == ".onnx" else "checkpoint"
    raise InputError(f"{what} not found", arg, here + one_of(str(arg), models,
                                                             what="give a .pt written by 'vctrain fit' or a name:"))
