"""A file gait-tuner writes is the old one or the whole new one: a full disk, a quota or an error
half-way leaves what was there (``gaits/files.py``), and the CLI says so in one line, exit 3.

The full disk is real, not mocked: the CLI runs in a child whose file-size limit
(``RLIMIT_FSIZE``, SIGXFSZ ignored) is below the joint table's size, so the kernel refuses the
write half-way (EFBIG), exactly where a filling disk refuses it (ENOSPC).
"""

from __future__ import annotations

import errno
import os
import resource
import signal
import subprocess

import pytest

from pathlib import Path

from gaits.files import FOLDER_REFUSED, FolderRefused, make_folder, probe_folder, write_text_atomic


def test_writes_the_whole_text_and_replaces_the_old(tmp_path):
    p = tmp_path / "sub" / "a.yaml"
    write_text_atomic(p, "old\n")
    write_text_atomic(p, "new é\n")
    assert p.read_text(encoding="utf-8") == "new é\n"
    assert sorted(x.name for x in p.parent.iterdir()) == ["a.yaml"]


def test_a_folder_the_file_system_refuses_is_named_as_such(tmp_path, monkeypatch):
    """mkdir with its parents says ENOENT only where no folder can be made (/proc): FolderRefused,
    naming the folder; any other error goes on as it was."""
    real = Path.mkdir

    def refusing(self, *a, **kw):
        if self.name == "nowhere":
            raise FileNotFoundError(errno.ENOENT, "No such file or directory", str(self))
        return real(self, *a, **kw)
    monkeypatch.setattr(Path, "mkdir", refusing)
    with pytest.raises(FolderRefused) as info:
        write_text_atomic(tmp_path / "nowhere" / "a.yaml", "x")
    assert info.value.errno == errno.ENOENT and info.value.filename == str(tmp_path / "nowhere")
    assert info.value.strerror == FOLDER_REFUSED
    assert make_folder(tmp_path / "a" / "b") == tmp_path / "a" / "b" and (tmp_path / "a" / "b").is_dir()
    (tmp_path / "f").write_text("x")
    with pytest.raises(FileExistsError):
        make_folder(tmp_path / "f")


def test_a_folder_probed_before_long_work_is_left_as_it_was(tmp_path):
    """probe_folder says before the work what make_folder would say after it, and leaves nothing."""
    assert probe_folder(tmp_path / "a" / "b" / "c") == tmp_path / "a" / "b" / "c"
    assert list(tmp_path.iterdir()) == []
    (tmp_path / "kept").mkdir()
    assert probe_folder(tmp_path / "kept" / "new") and sorted(p.name for p in tmp_path.iterdir()) == ["kept"]
    assert list((tmp_path / "kept").iterdir()) == []
    (tmp_path / "f").write_text("x")
    with pytest.raises(NotADirectoryError):
        probe_folder(tmp_path / "f" / "sub")
    with pytest.raises(FileExistsError):
        probe_folder(tmp_path / "f")
    if os.path.isdir("/proc/self"):
        with pytest.raises(FolderRefused):
            probe_folder("/proc/gait-tuner-none/sub")


def test_an_error_half_way_leaves_the_old_file_and_no_temporary(tmp_path, monkeypatch):
    p = tmp_path / "a.yaml"
    p.write_text("old\n", encoding="utf-8")

    def full(fd):
        raise OSError(errno.ENOSPC, "No space left on device")
    monkeypatch.setattr(os, "fsync", full)
    with pytest.raises(OSError) as info:
        write_text_atomic(p, "new\n" * 1000)
    assert info.value.errno == errno.ENOSPC and info.value.filename == str(p)
    assert p.read_text(encoding="utf-8") == "old\n"
    assert [x.name for x in tmp_path.iterdir()] == ["a.yaml"]


def test_a_figure_is_the_old_one_or_the_whole_new_one(tmp_path, monkeypatch):
    """Pictures (versus.png, compare.png, the plots) are rendered in memory and put in place: a
    full disk leaves the old picture (before: a partial PNG replaced it)."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from tuner.report.plots import save_figure
    p = tmp_path / "versus.png"
    p.write_bytes(b"old picture")
    fig, ax = plt.subplots()
    ax.plot([0, 1], [1, 0])

    def full(fd):
        raise OSError(errno.ENOSPC, "No space left on device")
    monkeypatch.setattr(os, "fsync", full)
    with pytest.raises(OSError):
        save_figure(fig, p, 50)
    assert p.read_bytes() == b"old picture" and [x.name for x in tmp_path.iterdir()] == ["versus.png"]
    monkeypatch.undo()
    save_figure(fig, p, 50)
    plt.close(fig)
    assert p.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_a_new_file_gets_the_usual_permissions(tmp_path):
    p = write_text_atomic(tmp_path / "n.txt", "x")
    umask = os.umask(0)
    os.umask(umask)
    assert p.stat().st_mode & 0o777 == 0o666 & ~umask


def _limit_file_size():
    signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
    resource.setrlimit(resource.RLIMIT_FSIZE, (20_000, 20_000))


def test_the_cli_on_a_full_disk_leaves_the_old_files_and_says_so(gait_tuner_cmd, run_env, tmp_path):
    out = tmp_path / "tk"
    out.mkdir()
    (out / "joints.csv").write_text("old table\n", encoding="utf-8")
    env = dict(run_env, PYTHONDONTWRITEBYTECODE="1", MPLCONFIGDIR=str(tmp_path / "mpl"))
    r = subprocess.run(gait_tuner_cmd + ["trajectory", "--params", "tkux-table2", "--out", str(out)],
                       capture_output=True, text=True, env=env, preexec_fn=_limit_file_size, timeout=600)
    assert r.returncode == 3, (r.stdout, r.stderr)
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("gait-tuner: error: "), r.stderr
    assert "joints.csv" in lines[0] and "Traceback" not in r.stderr
    assert (out / "joints.csv").read_text(encoding="utf-8") == "old table\n"
    assert not [x for x in out.iterdir() if x.name.endswith(".tmp")]
    # and with room, the same command writes it whole
    r = subprocess.run(gait_tuner_cmd + ["trajectory", "--params", "tkux-table2", "--out", str(out)],
                       capture_output=True, text=True, env=env, timeout=600)
    assert r.returncode == 0, r.stderr
    assert (out / "joints.csv").stat().st_size > 20_000
