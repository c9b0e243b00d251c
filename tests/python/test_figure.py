"""omnipose-figure and the README's Python example: pictures of a run, from its MCAP file and
from the library, checked as images (size, not blank) and for what they show."""

import pathlib
import re
import struct

import numpy as np
import pytest

from omnipose import run_figure
from omnipose.mcap_export import main as mcap_main, read_run

pytest.importorskip("matplotlib")
pytest.importorskip("mcap.reader")
pytest.importorskip("foxglove")

README = pathlib.Path(__file__).resolve().parents[2] / "README.md"


def png_size(path):
    data = pathlib.Path(path).read_bytes()
    assert data[:8] == b"\x89PNG\r\n\x1a\n", f"{path} is not a PNG"
    return struct.unpack(">II", data[16:24])  # IHDR width, height


def png_pixels(path):
    import matplotlib.image as mpimg
    return mpimg.imread(path)


@pytest.fixture(scope="module")
def run_mcap(tmp_path_factory, dataset_dir):
    out = tmp_path_factory.mktemp("figure") / "run.mcap"
    assert mcap_main([str(dataset_dir), str(out)]) == 0
    return out


def test_the_figure_shows_a_pictured_frame_and_the_heading(run_mcap, dataset_dir, tmp_path):
    out = tmp_path / "run.png"
    assert run_figure.main([str(run_mcap), str(out), "--groundtruth",
                            str(dataset_dir / "groundtruth.tum"), "--title", "test"]) == 0
    assert png_size(out) == (1000, 850)
    pixels = png_pixels(out)
    assert pixels[..., :3].std() > 0.05  # drawn, not blank
    run = read_run(run_mcap)
    pictured = {round(t * 1e-9, 6) for t, _, _ in run["/omnipose/panorama"]}
    windows = [w for _, _, w in run["/omnipose/windows"]]
    times = {m["sequence"]: round(t * 1e-9, 6) for t, _, m in run["/omnipose/motion"]}
    shown = run_figure.choose_frame(windows, {s for s, t in times.items() if t in pictured})
    assert times[shown["sequence"]] in pictured
    # The one whose fitted du varies most among the pictured frames.
    assert np.ptp(shown["model_du"]) == max(
        np.ptp(w["model_du"]) for w in windows if times[w["sequence"]] in pictured)


def test_a_frame_without_windows_or_a_file_without_a_run_is_an_error(run_mcap, tmp_path, capsys):
    assert run_figure.main([str(run_mcap), str(tmp_path / "x.png"), "--sequence", "999"]) == 1
    assert "frame 999 has no windows" in capsys.readouterr().err
    empty = tmp_path / "empty.mcap"
    empty.write_bytes(b"not an mcap file")
    assert run_figure.main([str(empty), str(tmp_path / "y.png")]) == 1
    assert "empty.mcap" in capsys.readouterr().err


def test_the_readme_example_runs(dataset_dir, tmp_path, monkeypatch):
    text = README.read_text()
    block = re.search(r"<!-- example: run figure -->\s*```python\n(.*?)```", text, re.S)
    assert block, "README.md has no run-figure example"
    code = block.group(1)
    assert len(code.strip().splitlines()) <= 12
    monkeypatch.chdir(tmp_path)
    code = code.replace('"build/demo/dataset"', repr(str(dataset_dir)))
    exec(compile(code, "README.md example", "exec"), {})
    assert png_size(tmp_path / "run.png")[0] > 300
