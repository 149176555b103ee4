"""Input data, the bottom layer: the `Scene`, its checks, TOML in and out, safe expressions; it never imports
dolfinx. Registered names (models, time schemes) are checked through `names`, which imports nothing."""

from ..lazy import lazy_names

# Imported on first use (PEP 562): the command line reads `scene.names` without NumPy (0.08 s sooner).
_LAZY = {"check_petsc_options": "checks", "Scene": "scene", "SceneWarning": "scene", "ModelConstant": "parameters",
         **dict.fromkeys(("BYTES_PER_STORED_NODE", "FIELD_KEYS", "FILE_KEYS", "MAX_FILE_BYTES", "MAX_OUTPUT_TIMES",
                          "MAX_STORED_BYTES", "REQUIRED_KEYS", "STORED_ROWS", "stored_bytes"), "limits"),
         **dict.fromkeys(("list_scenes", "load_scene", "scene_to_toml"), "toml")}
__getattr__, __dir__ = lazy_names(__name__, _LAZY, globals())

__all__ = ["BYTES_PER_STORED_NODE", "FIELD_KEYS", "FILE_KEYS", "MAX_FILE_BYTES", "MAX_OUTPUT_TIMES",
           "MAX_STORED_BYTES", "REQUIRED_KEYS", "STORED_ROWS", "ModelConstant", "Scene", "SceneWarning",
           "check_petsc_options", "list_scenes", "load_scene", "scene_to_toml", "stored_bytes"]
