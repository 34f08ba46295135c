"""vctrain: train, predict and evaluate road segmentation in the virtual-camera domain."""
__version__ = "0.1.0"
