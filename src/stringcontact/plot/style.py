"""How a run's pictures are written (`Look`): formats, size and matplotlib style sheet (``styles/NAME.mplstyle``); their
colours: contact red (the charts' too), a free string or membrane's blue, the obstacle's grey, and the yellow edge of a
membrane's contact set where it is coloured by a field. The pyvista pictures are a render in a matplotlib figure for vector words: VTK's own vector export (GL2PS, VTK
9.7.2) embeds the scene as a raster too, and writes "η" as "Œ∑"."""

from __future__ import annotations

import functools
from dataclasses import dataclass
from pathlib import Path

#: the files a picture may be written as (`Look.formats`): matplotlib's `savefig` formats
FORMATS = ("png", "pdf", "svg")
#: the style sheets (``styles/NAME.mplstyle``): name -> (default size (width, height) in inches, whether a caption line
#: gives the run's details, the size of the pyvista pictures' tick labels against the screen's)
STYLES = {"screen": ((11.0, 9.0), True, 1.0), "paper": ((7.0, 5.6), False, 0.7)}
#: the pictures' colours
CONTACT_COLOUR = "#b2182b"
FREE_COLOUR = "#92c5de"
OBSTACLE_COLOUR = "#777777"
MEMBRANE_OBSTACLE_COLOUR = "#c9c9c9"  # OBSTACLE_COLOUR at opacity 0.4 on white
#: the edge of the contact set of a membrane coloured by a field: yellow, seen on blue, grey and red alike
CONTACT_EDGE_COLOUR = "#ffd400"
#: the pixels per inch the pyvista pictures' font sizes are chosen for (a picture at the style's resolution scales them)
SCREEN_DPI = 100
#: the pixels of a run's pictures by default (the screen style's size at `SCREEN_DPI`)
WINDOW_SIZE = (1100, 900)
#: the sizes (inches) a picture may take
SMALLEST, LARGEST = 2.0, 40.0


@dataclass(frozen=True)
class Look:
    """How the pictures are written: every format of `formats` (``"png"``, ``"pdf"``, ``"svg"``), style sheet `style`
    (``"screen"``, or ``"paper"``: 8-point text 7 inches wide, 300 dpi), `size` (width, height) in inches (None: the
    style's); ``membrane.gif`` only with a raster format. A ValueError names a wrong option and its range."""

    formats: tuple = ("png",)
    style: str = "screen"
    size: tuple | None = None

    def __post_init__(self) -> None:
        formats = (self.formats,) if isinstance(self.formats, str) else tuple(self.formats)
        if not formats or any(f not in FORMATS for f in formats):
            raise ValueError(f"formats: expected some of {', '.join(FORMATS)}, got {self.formats!r}")
        object.__setattr__(self, "formats", tuple(dict.fromkeys(formats)))
        if self.style not in STYLES:
            raise ValueError(f"style: expected one of {', '.join(STYLES)}, got {self.style!r}")
        if self.size is not None:
            try:
                width, height = (float(v) for v in self.size)
            except (TypeError, ValueError):
                raise ValueError(f"size: expected (width, height) in inches, got {self.size!r}") from None
            if not (SMALLEST <= width <= LARGEST and SMALLEST <= height <= LARGEST):
                raise ValueError(f"size: width and height must be in {SMALLEST:g}..{LARGEST:g} inches, got {self.size!r}")
            object.__setattr__(self, "size", (width, height))

    @classmethod
    def of_pixels(cls, window_size, **kwargs) -> Look:
        """The look of a picture `window_size` pixels large on a screen (100 pixels an inch)."""
        return cls(size=(window_size[0] / SCREEN_DPI, window_size[1] / SCREEN_DPI), **kwargs)

    @property
    def inches(self) -> tuple[float, float]:
        """(width, height) of a space-time or 3-D picture."""
        return self.size or STYLES[self.style][0]

    @property
    def width(self) -> float:
        """The width of every picture, in inches."""
        return self.inches[0]

    @property
    def caption(self) -> bool:
        """Whether the pictures carry a caption line with the run's details (the screen style's do)."""
        return STYLES[self.style][1]

    @property
    def sheet(self) -> Path:
        """The matplotlib style sheet."""
        return Path(__file__).with_name("styles") / f"{self.style}.mplstyle"

    @functools.cached_property
    def dpi(self) -> float:
        """The PNG's dots per inch (the style sheet's ``savefig.dpi``)."""
        from matplotlib import rc_params_from_file

        return float(rc_params_from_file(self.sheet, use_default_template=False)["savefig.dpi"])

    def pixels(self, inches) -> tuple[int, int]:
        """The pixels of a raster `inches` (width, height) large at the style's resolution (a pyvista render)."""
        return tuple(max(16, round(v * self.dpi)) for v in inches)

    @property
    def zoom(self) -> float:
        """How much larger a pyvista render's fonts are than on a screen (pixels an inch, times the style's ticks)."""
        return self.dpi / SCREEN_DPI * STYLES[self.style][2]

    def paths(self, path) -> list[Path]:
        """`path` (a picture's name, ``.png``) in each format."""
        return [Path(path).with_suffix(f".{f}") for f in self.formats]

    def drawn(self):
        """Draw within (``with look.drawn():``): the style sheet's settings (matplotlib's `style.context`)."""
        import matplotlib.style

        return matplotlib.style.context(self.sheet)


#: the look of the pictures a run writes by default
SCREEN = Look()
