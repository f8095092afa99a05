"""The skin in the world.

The arm's kinematic chain (`kinematics`) and the material map of contacts in the world frame
(`map`); the map many robots share over Zenoh: its SQLite store (`map_store`), its service
(`map_service`, ``skin map serve``) and its client API (`shared_map.SharedMap`).
"""
