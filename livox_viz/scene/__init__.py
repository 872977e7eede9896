"""Stage 4, the world: scenes to cast into, and first-hit ray casting.

Takes a scene preset or a mesh file and gives a triangle mesh in world NED
(:mod:`~livox_viz.scene.scenes`) and a caster that answers, for rays, the distance
to their first hit (:mod:`~livox_viz.scene.raycast`: Embree, and trimesh's numpy
intersector for cross-checks).
"""
