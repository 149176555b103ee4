"""Input data, never imports dolfinx: the `Scene`, its validation, TOML in and out, safe expressions.

The bottom layer: it imports only `stringcontact.errors` (and NumPy, simpleeval). The names a scene may use
that are registered elsewhere (models, time schemes) are checked through `names`, which imports nothing.
"""

from .data import Scene, SceneWarning, list_scenes, load_scene, scene_to_toml

__all__ = ["Scene", "SceneWarning", "list_scenes", "load_scene", "scene_to_toml"]
