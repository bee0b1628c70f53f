"""Exports behave like every Unix tool's (files.replacing): `-` and /dev/stdout are standard output, a
symlink is written through and stays a link, a device or FIFO is written through and not replaced, a new
file gets the umask's mode, a replaced one keeps its own, and a failure changes nothing."""

from __future__ import annotations

import os
import stat
import subprocess
import sys
import threading

import pytest

from genr8_dist.files import TMP_PREFIX, is_stdout, is_stream, replace_atomically, replacing, temp_beside

QUERY = "select id, fitness from individuals order by id limit 4"


def _write(path, data: bytes) -> None:
    with replacing(path) as tmp:
        tmp.write_bytes(data)


@pytest.fixture(scope="module")
def run_dir(tmp_path_factory):
    from genr8_dist.store.synthetic import write_synthetic_run

    path = tmp_path_factory.mktemp("files") / "run"
    write_synthetic_run(path, 2, 3, 6, seed=1, generations_per_commit=3)
    return path


def _genr8(*args: str, cwd=None, umask: int | None = None, stdout=subprocess.PIPE):
    def set_umask() -> None:
        if umask is not None:
            os.umask(umask)

    return subprocess.run([sys.executable, "-m", "genr8_dist.cli", *map(str, args)], cwd=cwd, stdout=stdout,
                          stderr=subprocess.PIPE, preexec_fn=set_umask, check=False)


def _expected_csv(run_dir) -> bytes:
    from genr8_dist import history
    from genr8_dist.history._run import write_table

    table = history.query(run_dir, QUERY)
    out = run_dir.parent / "expected.csv"
    write_table(table, out, format="csv")
    return out.read_bytes()


@pytest.mark.parametrize("target", ["-", "/dev/stdout"])
def test_query_csv_to_standard_output_prints_the_rows(run_dir, target):
    done = _genr8("query", run_dir, QUERY, "--csv", target)
    assert done.returncode == 0, done.stderr
    assert done.stdout == _expected_csv(run_dir)
    assert done.stdout.count(b"\n") == 5                      # the header and 4 rows, nothing else
    assert b"wrote 4 rows" in done.stderr
    assert os.path.islink("/dev/stdout")                      # still the machine's link


def test_dev_stdout_redirected_to_a_file_appends_through_the_descriptor(run_dir, tmp_path):
    out = tmp_path / "out.csv"
    out.write_bytes(b"before\n")
    with open(out, "ab") as fh:
        done = _genr8("query", run_dir, QUERY, "--csv", "/dev/stdout", stdout=fh)
    assert done.returncode == 0, done.stderr
    assert out.read_bytes() == b"before\n" + _expected_csv(run_dir)


def test_a_parquet_to_standard_output_reads_back(run_dir):
    import io

    import pyarrow.parquet as pq

    done = _genr8("query", run_dir, QUERY, "--parquet", "-")
    assert done.returncode == 0, done.stderr
    assert pq.read_table(io.BytesIO(done.stdout)).num_rows == 4


def test_a_symlinked_output_stays_a_link_and_its_target_holds_the_rows(run_dir, tmp_path):
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    target = elsewhere / "rows.csv"
    target.write_text("old\n")
    os.chmod(target, 0o640)
    link = tmp_path / "link.csv"
    link.symlink_to(target)
    done = _genr8("query", run_dir, QUERY, "--csv", link)
    assert done.returncode == 0, done.stderr
    assert link.is_symlink() and os.readlink(link) == str(target)
    assert target.read_bytes() == _expected_csv(run_dir)
    assert stat.S_IMODE(target.stat().st_mode) == 0o640      # a replaced file keeps its mode
    assert not [p for p in elsewhere.iterdir() if p.name != "rows.csv"]   # no temporary left


def test_a_dangling_symlink_creates_its_target(tmp_path):
    link = tmp_path / "link.txt"
    link.symlink_to(tmp_path / "new.txt")
    _write(link, b"made\n")
    assert link.is_symlink() and (tmp_path / "new.txt").read_bytes() == b"made\n"


@pytest.mark.parametrize("mask, mode", [(0o022, 0o644), (0o077, 0o600), (0o002, 0o664)])
def test_a_new_export_gets_the_umask_mode(run_dir, tmp_path, mask, mode):
    out = tmp_path / f"new-{mask:o}.csv"
    done = _genr8("query", run_dir, QUERY, "--csv", out, umask=mask)
    assert done.returncode == 0, done.stderr
    assert stat.S_IMODE(out.stat().st_mode) == mode


def test_a_fifo_is_written_through_not_replaced(tmp_path):
    fifo = tmp_path / "pipe"
    os.mkfifo(fifo)
    got: list[bytes] = []
    reader = threading.Thread(target=lambda: got.append(fifo.read_bytes()))
    reader.start()
    _write(fifo, b"through the pipe\n")
    reader.join(timeout=10)
    assert got == [b"through the pipe\n"]
    assert stat.S_ISFIFO(os.lstat(fifo).st_mode)
    assert is_stream(fifo) and not is_stream(tmp_path)


def test_a_device_is_written_through(tmp_path):
    _write("/dev/null", b"nothing")
    assert stat.S_ISCHR(os.lstat("/dev/null").st_mode)


def test_a_failure_leaves_the_file_and_the_stream_untouched(tmp_path, capsysbinary):
    path = tmp_path / "keep.txt"
    path.write_bytes(b"kept\n")
    for target in (path, "-"):
        with pytest.raises(RuntimeError), replacing(target) as tmp:
            tmp.write_bytes(b"half")
            raise RuntimeError("stopped midway")
    assert path.read_bytes() == b"kept\n"
    assert capsysbinary.readouterr().out == b""
    assert sorted(p.name for p in tmp_path.iterdir()) == ["keep.txt"]


def test_dash_is_standard_output(capsysbinary):
    assert is_stdout("-")
    _write("-", b"to stdout\n")
    assert capsysbinary.readouterr().out == b"to stdout\n"


def test_gallery_and_report_write_to_standard_output(run_dir):
    done = _genr8("report", run_dir, "-o", "-", "-k", "2", "--gallery", "0")
    if done.returncode != 0 and b"matplotlib" in done.stderr:
        pytest.skip("the report needs matplotlib")
    assert done.returncode == 0, done.stderr
    assert done.stdout.lstrip().lower().startswith(b"<!doctype html")
    assert done.stdout.rstrip().endswith(b"</html>")
    assert b"wrote -" in done.stderr


def test_a_failed_rename_removes_its_temporary_and_leaves_the_target(tmp_path):
    """The one rename every atomic write uses (the store's too): a temporary named for the store's
    collector, gone again when the rename fails."""
    target = tmp_path / "taken"
    target.mkdir()
    (target / "inside").write_text("kept")
    tmp = temp_beside(target)
    assert os.path.dirname(tmp) == str(tmp_path)
    assert os.path.basename(tmp).startswith(f"{TMP_PREFIX}taken-{os.getpid()}-")
    with open(tmp, "wb") as fh:
        fh.write(b"new")
    with pytest.raises(OSError):
        replace_atomically(tmp, target, durable=True)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["taken"]
    assert (target / "inside").read_text() == "kept"
    done = tmp_path / "file"
    tmp = temp_beside(done)
    with open(tmp, "wb") as fh:
        fh.write(b"new")
    replace_atomically(tmp, done, durable=True)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["file", "taken"] and done.read_bytes() == b"new"
