"""vctrain: train, predict and evaluate road segmentation in the virtual-camera domain.

From Python (docs/api.md)::

    import cv2, vctrain
    model = vctrain.load("shipped")                      # a .pt, an exported .onnx, or a shipped name
    road = model.segment(cv2.imread("frame.png"), camera="kitti")   # BGR uint8 H x W x 3
    road.mask, road.prob                                 # H x W bool, float32 P(road), the frame's pixels

The names load on first use (torch with them): ``import vctrain`` stays light.
"""
__version__ = "0.1.0"

__all__ = ["load", "RoadModel", "Segmentation", "check_frame", "__version__"]

_API = ("load", "RoadModel", "Segmentation", "check_frame")  # vctrain.predict.model


def __getattr__(name: str):
    if name in _API:
        from .predict import model

        return getattr(model, name)
    raise AttributeError(f"module 'vctrain' has no attribute {name!r}")


def __dir__():
    return sorted(list(globals()) + list(_API))
