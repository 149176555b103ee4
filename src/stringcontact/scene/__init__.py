"""Input data, never imports dolfinx: the `Scene`, its validation, TOML in and out, safe expressions.

The bottom layer: it imports only `stringcontact.errors` (and NumPy, simpleeval, tomli-w). The names a scene may
use that are registered elsewhere (models, time schemes) are checked through `names`, which imports nothing.

Modules: `scene` (the `Scene` dataclass: building, derived values, conversions, warnings), `checks` (the
validation of each value, one-line `SceneError`s), `limits` (the keys and the limits on their values, the
stored rows' memory), `toml` (scene files in and out), `expressions`, `names`. `data` is the old single-module
path, kept as a re-export.
"""

from .checks import check_petsc_options
from .limits import (
    BYTES_PER_STORED_NODE,
    FIELD_KEYS,
    FILE_KEYS,
    MAX_FILE_BYTES,
    MAX_OUTPUT_TIMES,
    MAX_STORED_BYTES,
    REQUIRED_KEYS,
    STORED_ROWS,
    stored_bytes,
)
from .scene import Scene, SceneWarning
from .toml import list_scenes, load_scene, scene_to_toml

__all__ = [
    "BYTES_PER_STORED_NODE",
    "FIELD_KEYS",
    "FILE_KEYS",
    "MAX_FILE_BYTES",
    "MAX_OUTPUT_TIMES",
    "MAX_STORED_BYTES",
    "REQUIRED_KEYS",
    "STORED_ROWS",
    "Scene",
    "SceneWarning",
    "check_petsc_options",
    "list_scenes",
    "load_scene",
    "scene_to_toml",
    "stored_bytes",
]
