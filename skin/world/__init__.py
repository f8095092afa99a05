"""The skin in the world.

The arm's kinematic chain (`kinematics`) and the material map of contacts in the world frame
(`map`).
"""
