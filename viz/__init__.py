"""Views: the arm mesh with painted material labels (pyvista) and plots."""

from skin.viz.arm import ArmView
from skin.viz.arm_mesh import ArmLink, LinkGeometry, default_arm, load_arm

__all__ = ["ArmLink", "ArmView", "LinkGeometry", "default_arm", "load_arm"]
