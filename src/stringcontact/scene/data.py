"""The old path of the scene module (`stringcontact.scene.data`), kept so that existing imports keep working.

The scene now lives in modules of one concern each (`scene`, `checks`, `limits`, `toml`); new code imports
from `stringcontact.scene`.
"""

from . import *  # noqa: F403
from . import __all__  # noqa: F401
