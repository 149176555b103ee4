"""`io.publish`: the manifest that `--force` trusts, the marker that makes a partial folder removable, and the
target rules (docs/explanation/reliability.md, section Output)."""

import json
import os
from pathlib import Path

import pytest

from stringcontact.errors import OutputError
from stringcontact.io.publish import (
    MANIFEST,
    MARKER,
    atomic_path,
    check_target,
    foreign_file,
    open_partial,
    publish_partial,
    read_manifest,
)


def published(tmp_path, files: dict[str, str]) -> Path:
    """A folder published the way every command publishes one: open_partial, write, publish_partial."""
    target, lock, partial = open_partial(tmp_path / "out", force=False)
    try:
        assert (partial / MARKER).read_text() == "partial\n"
        for name, text in files.items():
            (partial / name).write_text(text)
        return publish_partial(partial, target, force=False)
    finally:
        lock.release()


def test_publishing_writes_the_manifest_and_drops_the_marker(tmp_path):
    out = published(tmp_path, {"summary.json": "{}", "a.csv": "1,2\n"})
    assert sorted(p.name for p in out.iterdir()) == ["a.csv", MANIFEST, "summary.json"]
    assert read_manifest(out) == {"a.csv": 4, "summary.json": 2}
    assert foreign_file(out) is None


@pytest.mark.parametrize("damage, reason", [
    (lambda out: (out / "notes.txt").write_text("mine"), "notes.txt is not a file stringcontact wrote there"),
    (lambda out: (out / "sub").mkdir(), "sub is not a file stringcontact wrote there"),
    (lambda out: (out / "a.csv").write_text("1,2,3\n"), "a.csv was changed after stringcontact wrote it (6 bytes, not 4)"),
    (lambda out: ((out / "a.csv").unlink(), (out / "a.csv").symlink_to("/etc/hostname")), "a.csv is not a file"),
    (lambda out: (out / MANIFEST).unlink(), f"has no {MANIFEST} of a stringcontact command"),
    (lambda out: (out / MANIFEST).write_text('{"written_by": "stringcontact", "files": {"a.csv": true}}'), "has no"),
    (lambda out: (out / MANIFEST).write_text('{"written_by": "me", "files": {"a.csv": 4}}'), "has no"),
    (lambda out: (out / MANIFEST).write_text("[]"), "has no"),
], ids=["added file", "added folder", "changed size", "symlink", "no manifest", "bool size", "not ours", "not a dict"])
def test_force_is_blocked_by_anything_the_manifest_does_not_list(tmp_path, damage, reason):
    out = published(tmp_path, {"summary.json": "{}", "a.csv": "1,2\n"})
    damage(out)
    assert reason in foreign_file(out)
    with pytest.raises(OutputError, match="--force replaces only a stringcontact result"):
        check_target(out, force=True)


def test_atomic_path_records_a_file_in_a_published_folder_only(tmp_path):
    out = published(tmp_path, {"summary.json": "{}"})
    with atomic_path(out / "energy.png") as tmp:
        tmp.write_bytes(b"png!")
    assert read_manifest(out) == {"energy.png": 4, "summary.json": 2} and foreign_file(out) is None
    plain = tmp_path / "plain"
    plain.mkdir()
    with atomic_path(plain / "x.csv") as tmp:
        tmp.write_text("1\n")
    assert sorted(os.listdir(plain)) == ["x.csv"]


def test_only_marked_partial_folders_of_killed_runs_are_removed(tmp_path):
    killed = tmp_path / ".out.partial-999999-abc"
    killed.mkdir()
    (killed / MARKER).write_text("partial\n")
    kept = tmp_path / ".out.partial-1-abcdefgh"  # a result a user saved under a reserved-looking name
    kept.mkdir()
    (kept / "summary.json").write_text(json.dumps({"status": "complete"}))
    other = tmp_path / ".out.partial-2-zzz"  # a marker that says something else
    other.mkdir()
    (other / MARKER).write_text("complete\n")
    with pytest.warns(UserWarning, match=r"removed 1 unfinished folder\(s\) .*\(\.out\.partial-999999-abc\)"):
        published(tmp_path, {"summary.json": "{}"})
    assert not killed.exists() and (kept / "summary.json").exists() and other.exists()


def test_a_mount_point_is_refused():
    mounted = next((p for p in ("/proc", "/sys", "/dev") if os.path.ismount(p)), None)
    if mounted is None:
        pytest.skip("no mount point among /proc, /sys, /dev")
    with pytest.raises(OutputError, match="is a mount point"):
        check_target(mounted, force=True)


def test_missing_parents_are_made_only_below_the_current_folder(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    assert check_target("a/b/c", force=False) == Path("a/b/c")
    with pytest.raises(OutputError, match=r"the folder .*/nowhere does not exist; create it first"):
        check_target(tmp_path.parent / "nowhere" / "x", force=False)


def test_a_swapped_out_result_is_removed_only_when_marked_old(tmp_path):
    published(tmp_path, {"summary.json": "{}"})  # the target exists now
    marked = tmp_path / ".out.old-999999-1"  # a --force swap killed after its second rename
    marked.mkdir()
    (marked / MARKER).write_text("old\n")
    users = tmp_path / ".out.old-1-2"  # a user's folder under a reserved-looking name
    users.mkdir()
    (users / "thesis.tex").write_text("years of work")
    fifo = tmp_path / ".out.partial-3-fifo"  # a FIFO planted as the marker: not read, never waited on
    fifo.mkdir()
    os.mkfifo(fifo / MARKER)
    target, lock, partial = open_partial(tmp_path / "out", force=True)
    lock.release()
    (partial / MARKER).unlink()
    partial.rmdir()
    assert not marked.exists() and (users / "thesis.tex").exists() and fifo.exists()


def test_a_folder_published_inside_a_result_does_not_block_force(tmp_path):
    """`make docs` runs `plot RUN --out RUN/pictures` and later `run --out RUN --force`."""
    out = published(tmp_path, {"summary.json": "{}"})
    target, lock, partial = open_partial(out / "pictures", force=False)
    (partial / "energy.png").write_bytes(b"png!")
    publish_partial(partial, target, force=False)
    lock.release()
    assert foreign_file(out) is None
    (out / "pictures" / "mine.txt").write_text("mine")
    assert foreign_file(out) == "pictures is not a file stringcontact wrote there"


def test_the_python_api_makes_the_missing_parents_it_is_given(tmp_path):
    """`simulate(output_dir=...)` and `staged_folder` make what they are asked to (the demos write so);
    only the command line's `check_target` refuses a missing parent outside the current folder."""
    out = published(tmp_path / "a" / "b", {"x.txt": "x"})
    assert (out / "x.txt").read_text() == "x"


def test_sync_soon_tolerates_a_missing_file(tmp_path):
    """The early sync only starts the writing; a file it cannot open is left to publishing's own fsync."""
    from stringcontact.io.publish import sync_soon

    (tmp_path / "there").write_bytes(b"x" * 4096)
    thread = sync_soon([tmp_path / "gone", tmp_path / "there"])
    thread.join()
    assert not thread.is_alive() and (tmp_path / "there").read_bytes() == b"x" * 4096


@pytest.mark.slow
def test_a_run_starts_writing_its_data_to_disk_before_its_pictures(tmp_path, monkeypatch):
    """solution.h5, rows.npz and diagnostics.csv, whole, go to the device while the pictures are drawn."""
    import stringcontact as sc
    from stringcontact.io import folder

    synced, order = [], []
    monkeypatch.setattr(folder, "sync_soon", lambda paths: synced.append([(p.name, p.stat().st_size) for p in paths]))

    def draw(result, partial):
        order.append(("pictures", len(synced)))

    scene = sc.load_scene("example1").replace(nx=20, nt=40, eps=0.01)
    sc.simulate(scene, output=sc.Output(tmp_path / "out", pictures=draw))
    [files] = synced
    assert order == [("pictures", 1)]  # started before the pictures
    assert [name for name, _ in files] == ["solution.h5", "rows.npz", "diagnostics.csv"]
    assert {name: size for name, size in files} == {name: (tmp_path / "out" / name).stat().st_size for name, _ in files}
