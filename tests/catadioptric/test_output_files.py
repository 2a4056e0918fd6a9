"""Outputs the system will not take (a folder no file may be made in, a full disk): one line, nothing left.

`/proc` takes no new files and `/dev/full` refuses every write with ENOSPC, whoever runs the tests (root
included, which a read-only folder would not stop).
"""

from pathlib import Path

import cv2
import numpy as np
import pytest

from catadioptric.cli import main
from catadioptric.errors import CatadioptricError
from catadioptric.outputs import OutputSet

pytestmark = pytest.mark.skipif(not (Path("/proc/self").is_dir() and Path("/dev/full").exists()),
                                reason="needs Linux's /proc and /dev/full")

SMALL = """[camera]
resolution = [64, 48]
focal_px = [150.0, 150.0]
position = [0.0, 0.0, 0.55]
look_at = [0.0, 0.0, 0.0]
up = [0.0, 1.0, 0.0]

[mirror]
type = "cylinder"
radius = 0.1
height = 0.49
center = [0.0, 0.0, 0.0]
axis = [0.0, 1.0, 0.0]
"""


@pytest.fixture()
def setup(tmp_path):
    path = tmp_path / "small.toml"
    path.write_text(SMALL)
    return path


@pytest.mark.parametrize("argv, message", [
    (["simulate", "{setup}", "-o", "/proc/x.png", "--spp", "1"], "/proc/x.gt.npz: cannot write in /proc ("),
    (["design", "{setup}", "--plot", "/proc/x.png"], "/proc/x.png: cannot write in /proc ("),
    (["design", "{setup}", "--report", "/proc/rep"], "/proc/rep: cannot make the report's folder ("),
    (["demo", "-o", "/proc/rep"], "/proc/rep: cannot make the report's folder ("),
    (["depthmap", "{image}", "--xslit", "0.1", "0.5", "30", "120", "--pitch", "0.0005", "0.0005", "-o",
      "/proc/d/x.png"], "/proc/d/x.png: -o: cannot make the folder /proc/d ("),
])
def test_an_output_the_system_refuses_gets_one_line_and_exit_1(capfd, tmp_path, setup, argv, message):
    image = tmp_path / "lines.png"  # lines at random angles: some carry a depth under this XSlit
    rng = np.random.default_rng(0)
    picture = np.full((120, 160), 200, np.uint8)
    for x0, y0, a, length in zip(rng.integers(0, 160, 40), rng.integers(0, 120, 40), rng.uniform(0, np.pi, 40),
                                 rng.uniform(20, 60, 40)):
        end = (int(x0 + length * np.cos(a)), int(y0 + length * np.sin(a)))
        cv2.line(picture, (int(x0), int(y0)), end, 30, 2)
    cv2.imwrite(str(image), picture)
    before = sorted(p.name for p in tmp_path.iterdir())
    code = main([a.format(setup=setup, image=image) for a in argv])
    out, err = capfd.readouterr()
    assert code == 1
    lines = err.splitlines()
    assert len(lines) == 1 and lines[0].startswith("catadioptric: error: "), err
    assert message in lines[0], lines[0]
    assert sorted(p.name for p in tmp_path.iterdir()) == before


def test_a_full_disk_names_the_output_and_leaves_no_file(tmp_path, monkeypatch):
    real = OutputSet.path_for

    def on_a_full_disk(self, final):  # b.json's staged file refuses its writes as a full disk does
        tmp = real(self, final)
        if Path(final).name == "b.json":
            tmp.unlink()
            tmp.symlink_to("/dev/full")
        return tmp

    monkeypatch.setattr(OutputSet, "path_for", on_a_full_disk)
    (tmp_path / "first.txt").write_text("kept")
    with pytest.raises(CatadioptricError, match=r"b\.json: cannot write \(No space left on device\)$"):
        with OutputSet() as o:
            o.write_text(tmp_path / "a.json", "{}")
            o.write_bytes(tmp_path / "b.json", b"x" * 10)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["first.txt"]
    assert (tmp_path / "first.txt").read_text() == "kept"


def test_a_write_of_a_staged_file_by_other_code_names_the_output_not_its_temporary(tmp_path):
    with pytest.raises(CatadioptricError, match=r"c\.npz: cannot write \("):
        with OutputSet() as o:
            tmp = o.path_for(tmp_path / "c.npz")
            raise PermissionError(13, "Permission denied", str(tmp))  # as np.savez or savefig would raise it
    assert list(tmp_path.iterdir()) == []


def test_an_unrelated_error_passes_through_and_the_staged_files_go(tmp_path):
    with pytest.raises(FileNotFoundError):
        with OutputSet() as o:
            o.write_text(tmp_path / "d.json", "{}")
            open(tmp_path / "nowhere" / "e.txt")
    assert list(tmp_path.iterdir()) == []


def test_a_disk_filling_up_under_a_command_gets_one_line_and_leaves_no_file(capfd, tmp_path, setup, monkeypatch):
    real = OutputSet.path_for

    def on_a_full_disk(self, final):  # numpy writes the ground truth's archive itself, into its staged file
        tmp = real(self, final)
        if str(final).endswith(".gt.npz"):
            tmp.unlink()
            tmp.symlink_to("/dev/full")
        return tmp

    monkeypatch.setattr(OutputSet, "path_for", on_a_full_disk)
    before = sorted(p.name for p in tmp_path.iterdir())
    code = main(["simulate", str(setup), "-o", str(tmp_path / "m.png"), "--spp", "1"])
    out, err = capfd.readouterr()
    assert code == 1
    assert len(err.splitlines()) == 1, err
    assert err.startswith(f"catadioptric: error: {tmp_path / 'm.gt.npz'}: cannot write ("), err
    assert sorted(p.name for p in tmp_path.iterdir()) == before


def test_any_other_oserror_of_a_command_is_one_line_naming_its_file(capfd, setup, monkeypatch):
    import catadioptric.design

    def refused(*args, **kwargs):  # what the system says of a file no check of ours foresaw
        raise PermissionError(13, "Permission denied", "/somewhere/cache.bin")

    monkeypatch.setattr(catadioptric.design, "fit_tile_map", refused)
    code = main(["fit", str(setup), "--tiles", "2"])
    out, err = capfd.readouterr()
    assert code == 1
    assert err.splitlines() == ["catadioptric: error: /somewhere/cache.bin: Permission denied"], err


def test_depthmap_writes_its_image_and_depths_together_or_neither(capfd, tmp_path):
    image = tmp_path / "lines.png"
    rng = np.random.default_rng(0)
    picture = np.full((120, 160), 200, np.uint8)
    for x0, y0, a, length in zip(rng.integers(0, 160, 40), rng.integers(0, 120, 40), rng.uniform(0, np.pi, 40),
                                 rng.uniform(20, 60, 40)):
        cv2.line(picture, (int(x0), int(y0)), (int(x0 + length * np.cos(a)), int(y0 + length * np.sin(a))), 30, 2)
    cv2.imwrite(str(image), picture)
    (tmp_path / "depth.png").mkdir()  # a folder where the image should go: no file can replace it
    argv = ["depthmap", str(image), "--xslit", "0.1", "0.5", "30", "120", "--pitch", "0.0005", "0.0005"]
    code = main(argv + ["-o", str(tmp_path / "depth.png")])
    out, err = capfd.readouterr()
    assert code == 1
    assert err.splitlines() == [f"catadioptric: error: {tmp_path / 'depth.png'}: cannot write (Is a directory)"]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["depth.png", "lines.png"]
    assert main(argv + ["-o", str(tmp_path / "ok.png")]) == 0  # the same image and XSlit, written where it can be
    assert (tmp_path / "ok.npy").is_file() and (tmp_path / "ok.png").is_file()
