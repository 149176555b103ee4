"""Input data, the bottom layer: the `Scene`, its checks, TOML in and out, safe expressions; it never imports
dolfinx. Registered names (models, time schemes) are checked through `names`, which imports nothing."""

import lazy_loader as _lazy

# Imported on first use (SPEC 1: lazy_loader): the command line reads `scene.names` without NumPy (0.08 s sooner).
__getattr__, __dir__, _ = _lazy.attach(__name__, submod_attrs={
    "checks": ["check_petsc_options"], "scene": ["Scene", "SceneWarning"], "parameters": ["ModelConstant"],
    "limits": ["BYTES_PER_STORED_NODE", "FIELD_KEYS", "FILE_KEYS", "MAX_FILE_BYTES", "MAX_OUTPUT_TIMES",
               "MAX_STORED_BYTES", "REQUIRED_KEYS", "STORED_ROWS", "stored_bytes"],
    "toml": ["list_scenes", "load_scene", "scene_to_toml"]})

__all__ = ["BYTES_PER_STORED_NODE", "FIELD_KEYS", "FILE_KEYS", "MAX_FILE_BYTES", "MAX_OUTPUT_TIMES",
           "MAX_STORED_BYTES", "REQUIRED_KEYS", "STORED_ROWS", "ModelConstant", "Scene", "SceneWarning",
           "check_petsc_options", "list_scenes", "load_scene", "scene_to_toml", "stored_bytes"]
