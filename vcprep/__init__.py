"""vcprep: reproject road images from any camera into one standard virtual camera (VCSeg).

From Python (docs/api.md)::

    import cv2, vcprep
    cam = vcprep.load_cameras("camvid")                 # a preset, a camera YAML or calibration file
    warped = vcprep.warp_frame(cv2.imread("frame.png"), cam)   # the frame in the virtual camera
    back = warped.back(warped.image[..., 1])            # anything computed there, in the frame's pixels

The names load on first use: ``import vcprep`` stays light.
"""
__version__ = "0.1.0"

# name -> the module that defines it (each loaded on first use)
_NAMES = {"Camera": "camera.pinhole", "PRESETS": "camera.pinhole", "load_cameras": "camera.sources",
          "camera_from_spec": "camera.spec", "warp_frame": "warp.frame", "WarpedFrame": "warp.frame",
          "VCError": "errors", "InputError": "errors"}

__all__ = [*_NAMES, "__version__"]


def __getattr__(name: str):
    if name in _NAMES:
        import importlib

        return getattr(importlib.import_module(f"{__name__}.{_NAMES[name]}"), name)
    raise AttributeError(f"module 'vcprep' has no attribute {name!r}")


def __dir__():
    return sorted(list(globals()) + list(_NAMES))
