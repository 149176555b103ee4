"""``membrane.gif``: a 2-D run as an animation, drawn with pyvista (off-screen) and written by Pillow.

One plotter holds the scene of `membrane.add_membrane` (the membrane coloured by contact, the
obstacle in grey); each frame changes the membrane's heights and contact colours and the title in place,
so a frame costs one render and one GIF frame, not a new scene. The frames are every k-th stored row (and
the last), at most `max_frames` of them: the membrane falls, lands, and its contact patches spread and
shrink. A membrane with a surface field (`membrane.MembraneView.field`) is coloured by it on one scale for
all frames (its bar at the right), the edge of its contact set drawn in yellow and moved with each frame.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
from PIL import Image

from ..io.manifest import atomic_path
from .colour_bar import add_field_bar
from .membrane import (
    add_contact_edge,
    add_membrane,
    add_membrane_axes,
    contact_edge,
    membrane_colours,
    membrane_label,
    membrane_title,
    membrane_view,
    show_row,
)
from .mesh_pictures import _every_kth
from .picture_names import WINDOW_SIZE
from .vtk_start import _font_file, _plotter

MAX_FRAMES = 50
FPS = 12
#: the GIF's pixels, as a share of the pictures' window size: 1100x900 -> 660x540 (docs/explanation/visualisation.md)
SIZE_SHARE = 0.6
#: colours of the GIF: two shaded surface colours, the grey obstacle and black text need few
PALETTE = 64
#: of a GIF coloured by a field: its colours' blends (blue through grey to red, say), shaded. Against its
#: unquantised frames (a 12x12 film_drum, 41 frames): 64 colours, mean error 1.91 and 99th percentile 10 of 255;
#: 128 and 256: 1.69, 8
FIELD_PALETTE = 128
#: where a field's colour bar stands in the frame (x0, y0, x1, y1, 0 … 1): the upper right, clear of the axes
FIELD_BAR = (0.955, 0.45, 0.975, 0.86)
#: font sizes (points) of the frame's caption (time, contact area, patches: letters about 15 px high) and of
#: the title; the caption was 6 points (8 px)
CAPTION_FONT = 11
TITLE_FONT = 8


def frame_rows(result, max_frames: int = MAX_FRAMES) -> np.ndarray:
    """The stored rows drawn as frames: every k-th row and the last, at most about `max_frames`."""
    return _every_kth(len(result.t), max_frames)


def gif_size(window_size) -> tuple[int, int]:
    """The GIF's width and height: `SIZE_SHARE` of `window_size`, even numbers."""
    return tuple(2 * round(SIZE_SHARE * v / 2) for v in window_size)


def membrane_animation(result, path, window_size=WINDOW_SIZE, max_frames: int = MAX_FRAMES, fps: float = FPS) -> Path:
    """``membrane.gif``: the membrane z = η(x, y, t) at every few stored rows, red where in contact (or coloured
    by its surface field, the contact set's edge in yellow), above the obstacle (grey), the time, contact
    area and number of contact patches in the title of each frame."""
    path = Path(path)
    rows = frame_rows(result, max_frames)
    view = membrane_view(result)
    area = result.contact_measure
    patches = dataclasses.replace(result, contact=result.contact[rows]).contact_patches()  # of the frames only
    p = _plotter(gif_size(window_size))
    try:
        surface = add_membrane(p, result, rows[0], view)
        edge = None if view.field is None else add_contact_edge(p, surface, view)
        if view.field is not None:
            add_field_bar(p, view.field, FIELD_BAR, vertical=True, font_size=TITLE_FONT)
        add_membrane_axes(p, view)  # x, y and η with ticks, as in membrane.png (static: drawn once per frame's render)
        # the title below, the frame's time, contact area and patches above, each CAPTION_FONT high (15 px);
        # text actors of a fixed size: a corner annotation fits its font to the viewport anew at every render (3x the render time)
        words = f"{membrane_title(result, view, 'The membrane')}\n{membrane_colours(result, view, sep=chr(10))}"
        p.add_text(words, position=(0.02, 0.02), viewport=True,
                   font_size=TITLE_FONT, color="black", font_file=_font_file())
        text = p.add_text("", position=(0.02, 0.98), viewport=True, font_size=CAPTION_FONT, color="black", font_file=_font_file())
        text.prop.SetVerticalJustificationToTop()
        p.screenshot(None, return_img=True)  # pyvista's first render sets the window up; later ones only draw
        frames = []
        for k, i in enumerate(rows):
            show_row(surface, result, i, view)  # in place: the scene stays, the heights and colours change
            if edge is not None:
                contact_edge(surface, view, into=edge)
            text.input = membrane_label(result, i, area[i], int(patches[k]))
            p.render()
            frames.append(np.array(p.image))
    finally:
        p.close()
    write_gif(path, frames, fps, landmarks=[int(np.argmax(area[rows]))],
              colours=PALETTE if view.field is None else FIELD_PALETTE)
    return path


def write_gif(path: Path, frames: list, fps: float, landmarks=(), colours: int = PALETTE) -> None:
    """The RGB `frames` as a looping GIF at `fps`, written whole or not at all.

    All frames share one palette of `colours` colours, made from a few frames spread over the run and the
    `landmarks` (the frame of the largest contact area: its red must be in it), and are mapped onto it
    without dithering: 2 ms a frame, where Pillow's own median cut takes 50 ms for each (docs/explanation/visualisation.md).
    Pillow writes the frames with the palette attached: imageio's Pillow plugin, given the palette apart,
    wrote white as black with Debian's Pillow 9.4 (the one a fresh setup has).
    """
    spread = np.unique(np.concatenate([np.linspace(0, len(frames) - 1, 6).round().astype(int), list(landmarks)]))
    palette = Image.fromarray(np.concatenate([frames[k] for k in spread])).quantize(colours, method=Image.Quantize.FASTOCTREE)
    images = [Image.fromarray(f).quantize(palette=palette, dither=Image.Dither.NONE) for f in frames]
    with atomic_path(path) as tmp:
        images[0].save(tmp, format="GIF", save_all=True, append_images=images[1:], duration=round(1000 / fps), loop=0,
                       optimize=False)
