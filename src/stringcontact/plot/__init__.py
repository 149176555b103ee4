"""Pictures: matplotlib charts, pyvista mesh pictures, the membrane animation, the picture process.

Layer: imports `io` (atomic writes, read-back) and below; the writer in `io` never imports this package.
"""

import warnings as _warnings

# pip's matplotlib beside Debian's mpl_toolkits (python3-matplotlib) warns "Unable to import Axes3D" when its
# projections are first imported: by pyplot, or by pyvista's colour maps at any later time. No picture draws 3-D
# axes, and a user cannot act on it: the filter holds for the process once any picture module is imported.
_warnings.filterwarnings("ignore", message="Unable to import Axes3D")
