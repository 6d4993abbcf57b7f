"""tactile_viz: active tactile object recognition, pose estimation and shape transfer."""

__version__ = "0.1.0"
