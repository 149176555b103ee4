import os
import sys

# `python -m stringcontact` puts the current folder first on sys.path: a ufl.py or pyvista.py there would be imported
# by the run. It goes before anything else is imported; `--model module:name` adds it back while it loads the model.
if (
    sys.path
    and sys.path[0]
    and os.path.realpath(sys.path[0]) == os.path.realpath(os.getcwd())
    and not sys.flags.safe_path
):
    del sys.path[0]

from .cli.main import main  # after the current folder left sys.path

sys.exit(main())
