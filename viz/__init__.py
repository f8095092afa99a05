"""Views: the arm mesh with painted material labels (pyvista) and plots."""

from skin.viz.arm import ArmView, LinkGeometry, default_arm

__all__ = ["ArmView", "LinkGeometry", "default_arm"]
