"""The 3D view of a finished job (viser): scene building, the job's data, the server.

``scene.build_scene(scene, result)`` draws one job; ``server.Viewer`` runs viser
inside the API process and gives every browser tab its own scene and controls.
"""
