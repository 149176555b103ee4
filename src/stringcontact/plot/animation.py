"""``membrane.gif``: a 2-D run's frames rendered by pyvista in one plotter (`membrane.rendered_rows`), written by
Pillow; a surface field's colour bar drawn once by matplotlib and laid over every frame."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from PIL import Image

from ..io.publish import atomic_path
from . import membrane
from .charts import figure
from .mesh_pictures import _every_kth
from .style import WINDOW_SIZE
from .vtk_start import _font_file, _plotter

MAX_FRAMES = 50
FPS = 12
#: the GIF's pixels, as a share of the pictures' window size: 1100x900 -> 660x540 (docs/explanation/visualisation.md)
SIZE_SHARE = 0.6
#: colours of the GIF: two shaded surface colours, the grey obstacle and black text need few
PALETTE = 64
#: of a GIF coloured by a field, its blends shaded: against the unquantised frames of a 12x12 film_drum (41 frames),
#: 64 colours give a mean error of 1.91 of 255 (99th percentile 10), 128 and 256 give 1.69 (8)
FIELD_PALETTE = 128
#: where a field's colour bar stands in the frame (x0, y0, x1, y1, 0 … 1): the upper right, clear of the axes
FIELD_BAR = (0.955, 0.45, 0.975, 0.86)
#: font sizes (points) of the frame's caption (time, contact area, patches: letters about 15 px high) and the title
CAPTION_FONT = 11
TITLE_FONT = 8


def frame_rows(result, max_frames: int = MAX_FRAMES) -> np.ndarray:
    """The stored rows drawn as frames: every k-th row and the last, at most about `max_frames`."""
    return _every_kth(len(result.t), max_frames)


def gif_size(window_size) -> tuple[int, int]:
    """The GIF's width and height: `SIZE_SHARE` of `window_size`, even numbers."""
    return tuple(2 * round(SIZE_SHARE * v / 2) for v in window_size)


def membrane_animation(result, path, window_size=WINDOW_SIZE, max_frames: int = MAX_FRAMES, fps: float = FPS) -> Path:
    """``membrane.gif``: the membrane at every few stored rows, coloured as ``membrane.png``, each frame titled with
    its time, contact area and patches."""
    rows = frame_rows(result, max_frames)
    view = membrane.membrane_view(result)
    labels = membrane.membrane_labels(result, rows)
    size = gif_size(window_size)
    bar = None if view.field is None else field_bar(view.field, size)
    p = _plotter(size)
    try:
        # text actors of a fixed size: a corner annotation fits its font to the viewport at every render (3x its time)
        words = (f"{view.title('The membrane')}\n"
                 f"{membrane.membrane_colours(result, view, sep=chr(10))}")
        p.add_text(words, position=(0.02, 0.02), viewport=True, font_size=TITLE_FONT, color="black",
                   font_file=_font_file())
        text = p.add_text("", position=(0.02, 0.98), viewport=True, font_size=CAPTION_FONT, color="black",
                          font_file=_font_file())
        text.prop.SetVerticalJustificationToTop()

        def caption(k, row):
            text.input = labels[k]

        frames = [image if bar is None else _laid_over(image, bar)
                  for image in membrane.rendered_rows(p, result, rows, view, before_render=caption)]
    finally:
        p.close()
    write_gif(Path(path), frames, fps, landmarks=[int(np.argmax(result.contact_measure[rows]))],
              colours=PALETTE if bar is None else FIELD_PALETTE)
    return Path(path)


def field_bar(scale, size) -> np.ndarray:
    """matplotlib's colour bar of `scale` at `FIELD_BAR` in a frame `size` pixels large, transparent around it (RGBA)."""
    fig = figure((size[0] / 100, size[1] / 100), layout=None, dpi=100)
    fig.patch.set_alpha(0.0)
    x0, y0, x1, y1 = FIELD_BAR
    ax = fig.add_axes((x0, y0, x1 - x0, y1 - y0))
    scale.colour_bar(fig, cax=ax)
    ax.yaxis.set_ticks_position("left")
    ax.tick_params(labelsize=CAPTION_FONT - 1)  # matplotlib's points at 100 pixels an inch: VTK's TITLE_FONT's size
    ax.set_title(scale.label, fontsize=CAPTION_FONT, loc="right", pad=10)
    fig.canvas.draw()
    return np.array(fig.canvas.buffer_rgba())


def _laid_over(frame: np.ndarray, overlay: np.ndarray) -> np.ndarray:
    alpha = overlay[..., 3:] / 255.0
    return (frame * (1.0 - alpha) + overlay[..., :3] * alpha).round().astype(np.uint8)


def write_gif(path: Path, frames: list, fps: float, landmarks=(), colours: int = PALETTE) -> None:
    """The RGB `frames` as a looping GIF at `fps`, written whole or not at all.

    All frames share one palette of `colours` colours, made from a few frames spread over the run and the
    `landmarks` (the frame of the largest contact area: its red must be in it), and are mapped onto it
    without dithering: 2 ms a frame, where Pillow's own median cut takes 50 ms for each (docs/explanation/visualisation.md);
    imageio's Pillow plugin, given the palette apart, wrote white as black with Debian's Pillow 9.4.
    """
    spread = np.unique(np.concatenate([np.linspace(0, len(frames) - 1, 6).round().astype(int), list(landmarks)]))
    palette = Image.fromarray(np.concatenate([frames[k] for k in spread])).quantize(colours, method=Image.Quantize.FASTOCTREE)
    images = [Image.fromarray(f).quantize(palette=palette, dither=Image.Dither.NONE) for f in frames]
    with atomic_path(path) as tmp:
        images[0].save(tmp, format="GIF", save_all=True, append_images=images[1:], duration=round(1000 / fps), loop=0,
                       optimize=False)
