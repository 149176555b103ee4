"""`stringcontact plot DIR --format png,pdf,svg --style paper`: Example 1's, the drum's and a plugin's field picture
as a paper takes them, read back by their readers: each PDF by pypdf (one page of the look's size, its words as
text with their Greek letters, its fonts embedded; the 3-D pictures' render an image at the style's resolution),
each SVG by an XML parser (its size, its words in matplotlib's comments), each PNG by Pillow (its pixels)."""

from __future__ import annotations

import xml.etree.ElementTree as ET

import numpy as np
import pytest
from PIL import Image

import stringcontact as sc
from stringcontact.cli.main import main
from stringcontact.io.readback import read_output
from stringcontact.plot import run_pictures as viz

pypdf = pytest.importorskip("pypdf", reason="the PDF reader the tests read the pictures with (pyproject's test extra)")

#: the titles a picture's PDF and SVG must carry as text
TITLES = {"contact_set": "Contact set {η ≤ 0} over (x, t)", "energy": "Energy balance (1.4)",
          "space_time": "Surface η(x, t) over the (x, t) plane", "membrane": "The membrane at the output times",
          "spring_force": "Ground spring force k η⁻"}


@pytest.fixture(scope="module")
def folders(tmp_path_factory):
    """Example 1 (with the plugin soft_ground's ground, whose field spring_force has a picture) and the drum, each
    written by `run` and drawn again by `plot` for a paper: {name: (the run's folder, the paper's pictures)}."""
    from stringcontact.model.registry import registered

    root = tmp_path_factory.mktemp("paper")
    model = "soft_ground" if "soft_ground" in registered() else None
    scenes = {"example1": sc.load_scene("example1").replace(nx=40, nt=600, model=model),
              "drum": sc.load_scene("drum").replace(mesh_size=0.25, T=0.3, nt=60, output_times=[0.0, 0.15, 0.3])}
    made = {}
    for name, scene in scenes.items():
        sc.simulate(scene, output=sc.Output(root / name, progress=False, pictures=False))
        assert main(["plot", str(root / name), "--out", str(root / f"{name}-paper"), "--format", "png,pdf,svg",
                     "--style", "paper"]) == 0
        made[name] = (root / name, root / f"{name}-paper")
    return made


def _fonts_embedded(page) -> list[bool]:
    """For each font of the PDF page: whether its TrueType program is in the file (FontFile2)."""
    found = []
    for font in page["/Resources"]["/Font"].values():
        font = font.get_object()
        described = font["/DescendantFonts"][0].get_object() if "/DescendantFonts" in font else font
        found.append("/FontFile2" in described["/FontDescriptor"].get_object())
    return found


def _images(page) -> list[tuple[int, int]]:
    objects = page["/Resources"].get("/XObject") or {}
    return [(int(o.get_object()["/Width"]), int(o.get_object()["/Height"])) for o in objects.values()
            if o.get_object().get("/Subtype") == "/Image"]


@pytest.mark.slow
@pytest.mark.parametrize("name", ["example1", "drum"])
def test_every_picture_is_a_pdf_an_svg_and_a_png_of_the_papers_size(folders, name):
    _, paper = folders[name]
    names = [n for n in viz.pictures_of(read_output(folders[name][0])) if n.endswith(".png")]
    assert sorted(p.name for p in paper.glob("*.pdf")) == sorted(n.replace(".png", ".pdf") for n in names)
    assert not list(paper.glob("*.gif")) or (paper / "membrane.png").exists()  # the GIF with a raster format only
    for png in names:
        stem = png[:-4]
        page = pypdf.PdfReader(paper / f"{stem}.pdf").pages[0]
        width, height = (float(v) for v in page.mediabox[2:])
        assert width == pytest.approx(7.0 * 72), stem  # the paper style: 7 inches wide
        text = page.extract_text()
        if stem in TITLES:
            assert TITLES[stem] in text, (stem, text[:300])
        assert all(_fonts_embedded(page)) and _fonts_embedded(page), stem
        svg = ET.parse(paper / f"{stem}.svg", parser=ET.XMLParser(target=ET.TreeBuilder(insert_comments=True))).getroot()
        assert svg.tag == "{http://www.w3.org/2000/svg}svg" and svg.get("width") == "504pt", stem
        assert float(svg.get("height").removesuffix("pt")) == pytest.approx(height, abs=0.5), stem
        comments = " ".join(c.text for c in svg.iter(ET.Comment))
        if stem in TITLES:
            assert TITLES[stem] in comments, stem
        with Image.open(paper / png) as image:
            assert image.size == (round(7.0 * 300), round(height / 72 * 300)), stem  # 300 dots per inch


@pytest.mark.slow
def test_the_3d_pictures_pdf_holds_the_render_at_the_papers_resolution_and_its_words_as_text(folders):
    for name, stem in (("example1", "space_time"), ("drum", "membrane")):
        page = pypdf.PdfReader(folders[name][1] / f"{stem}.pdf").pages[0]
        images = _images(page)
        assert images, stem
        widest = max(w for w, _ in images)
        assert widest >= (2000 if stem == "space_time" else 600), (stem, images)  # 300 dpi: 7 in (one column of 3)
        text = page.extract_text()
        assert "in contact, η ≤ 0" in text and "free, η > 0" in text, text  # the colour key: vector text


@pytest.mark.slow
def test_a_plugins_field_picture_is_a_pdf_with_its_label(folders):
    from stringcontact.model.registry import registered

    if "soft_ground" not in registered():
        pytest.skip("examples/soft_ground is not installed (scripts/setup installs it)")
    page = pypdf.PdfReader(folders["example1"][1] / "spring_force.pdf").pages[0]
    assert TITLES["spring_force"] in page.extract_text()


def test_a_column_sized_picture_is_that_size(tmp_path, capsys):
    """--size 3.4x2.8in: the 3-D and space-time pictures that size, the others that wide; --size in pixels is at the
    style's resolution."""
    from stringcontact.cli.plot import parse_size

    assert parse_size("3.4x2.8in") == (3.4, 2.8)
    assert parse_size("1020x840", dpi=300) == pytest.approx((3.4, 2.8))
    assert parse_size("17x12cm") == pytest.approx((17 / 2.54, 12 / 2.54))
    for bad in ("0.5x2in", "3x100in", "axbin", "10x10"):
        with pytest.raises(ValueError, match="--size"):
            parse_size(bad)


@pytest.mark.parametrize("argv, words", [(["--format", "jpg"], "--format: expected png, pdf, svg"),
                                         (["--style", "poster"], "--style"),
                                         (["--size", "3x100in"], "--size")])
def test_bad_format_style_or_size_is_one_line(tmp_path, capsys, argv, words):
    try:
        code = main(["plot", str(tmp_path), *argv])
    except SystemExit as stop:  # argparse's refusal of a choice
        code = stop.code
    assert code == 2
    err = capsys.readouterr().err.strip()
    assert words in err and "\n" not in err and not list(tmp_path.iterdir())


def test_output_takes_the_formats_style_and_size_and_checks_them():
    look_of = sc.Output("out", formats=("png", "pdf"), style="paper", size=(3.4, 2.8))
    assert (look_of.formats, look_of.style, look_of.size) == (("png", "pdf"), "paper", (3.4, 2.8))
    assert sc.Output("out", formats="svg").formats == ("svg",)
    for bad, words in (({"formats": ("png", "jpg")}, "formats: expected some of png, pdf, svg"),
                       ({"style": "poster"}, "style: expected one of screen, paper"),
                       ({"size": (1, 100)}, "size: width and height must be in")):
        with pytest.raises(ValueError, match=words):
            sc.Output("out", **bad)


@pytest.mark.slow
def test_a_run_writes_its_pictures_as_its_output_says(tmp_path):
    """`simulate(..., output=Output(DIR, formats=("pdf",), style="paper"))`: PDFs only, no GIF and no PNG."""
    scene = sc.load_scene("example1").replace(nx=40, nt=600)
    sc.simulate(scene, output=sc.Output(tmp_path / "run", formats=("pdf",), style="paper"))
    pdfs = sorted(p.name for p in (tmp_path / "run").glob("*.pdf"))
    assert pdfs == sorted(n.replace(".png", ".pdf") for n in viz.PICTURES)
    assert not list((tmp_path / "run").glob("*.png"))
    assert np.isclose(float(pypdf.PdfReader(tmp_path / "run" / "energy.pdf").pages[0].mediabox[2]), 7 * 72)
