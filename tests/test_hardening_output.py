"""Nothing is lost: atomic output, the input never overwritten, and interrupted runs
(Ctrl-C, a killed worker, a full disk) leave no partial file and say what happened."""

from __future__ import annotations

import contextlib
import errno
import io
import os
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
from click.testing import CliRunner

import fgslice.design
import fgslice.output
import fgslice.pipeline
from fgslice.cli import main
from fgslice.design import api
from fgslice.errors import OutputError, SliceError
from fgslice.executor import map_ordered
from fgslice.machine.gcode_reader import read_gcode
from fgslice.output import atomic_output, check_writable
from fgslice.pipeline import slice_to_gcode
from fgslice.settings import load_settings

FGSLICE = Path(sys.executable).with_name("fgslice")
BOX = 'fgrade(["x/40 + 0.5", "0.5 - x/40"], ["blue", "yellow"]) { rectprism(40, 20, 1); }\n'
OLD = "; an earlier print\nG1 X1 Y1\n"


def box_design():
    return api.design(api.fgrade(["x/40 + 0.5", "0.5 - x/40"], ["blue", "yellow"], api.rectprism(40, 20, 1)))


def leftovers(folder: Path) -> list[str]:
    return sorted(p.name for p in folder.iterdir() if p.name.endswith(".part"))


def test_atomic_output_replaces_only_with_a_complete_file(tmp_path):
    target = tmp_path / "out.gcode"
    target.write_text(OLD)
    with pytest.raises(ValueError):
        with atomic_output(target) as handle:
            handle.write("G1 X2 Y2\n" * 1000)
            handle.flush()
            assert Path(handle.name).stat().st_size == 9000 and target.read_text() == OLD
            raise ValueError("stop half way")
    assert target.read_text() == OLD and leftovers(tmp_path) == []
    with atomic_output(target) as handle:
        handle.write("G1 X3 Y3\n")
    assert target.read_text() == "G1 X3 Y3\n" and leftovers(tmp_path) == []


def test_input_is_never_the_output(tmp_path):
    design = tmp_path / "part.vcad"
    design.write_text(BOX)
    (tmp_path / "link.gcode").symlink_to(design)
    for output in (design, tmp_path / "link.gcode", tmp_path / "." / "part.vcad"):
        with pytest.raises(OutputError, match="is the input file"):
            check_writable(output, inputs=(design,))
    result = CliRunner().invoke(main, ["slice", str(design), "-o", str(tmp_path / "link.gcode"), "--jobs", "1"])
    assert result.exit_code == 2 and "refusing to overwrite it" in result.output
    assert design.read_text() == BOX


class _FullDisk(io.FileIO):
    """A file that takes ``room`` bytes, then fails as a full disk does."""

    room = 4096

    def write(self, data):
        if self.tell() + len(data) > self.room:
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
        return super().write(data)


def _full_disk_open(path, mode="r", encoding=None, newline=None):
    return io.TextIOWrapper(io.BufferedWriter(_FullDisk(path, "w")), encoding=encoding, newline=newline)


def test_full_disk_is_reported_and_leaves_nothing(tmp_path, monkeypatch):
    target = tmp_path / "out.gcode"
    target.write_text(OLD)
    monkeypatch.setattr(fgslice.output, "open", _full_disk_open, raising=False)
    with pytest.raises(OutputError) as info:
        slice_to_gcode(box_design(), load_settings(), target, jobs=1)
    assert "the disk is full" in info.value.message and "nothing was written" in info.value.message
    assert "previous file is unchanged" in info.value.message and "free space" in info.value.hint
    assert target.read_text() == OLD and leftovers(tmp_path) == []


@pytest.fixture
def tiny_tmpfs(tmp_path):
    """A 16 KiB tmpfs (needs root); skips where mounting is not allowed."""
    mount = tmp_path / "small"
    mount.mkdir()
    if os.geteuid() != 0 or not shutil.which("mount"):
        pytest.skip("mounting a tmpfs needs root")
    done = subprocess.run(["mount", "-t", "tmpfs", "-o", "size=16k", "tmpfs", str(mount)], capture_output=True)
    if done.returncode:
        pytest.skip(f"cannot mount a tmpfs: {done.stderr.decode(errors='replace').strip()}")
    try:
        yield mount
    finally:
        subprocess.run(["umount", str(mount)], check=True)


def test_real_full_disk_through_the_command_line(tiny_tmpfs, tmp_path):
    design = tmp_path / "box.vcad"
    design.write_text(BOX)
    target = tiny_tmpfs / "box.gcode"
    target.write_text(OLD)
    done = subprocess.run([FGSLICE, "slice", design, "-o", target, "--jobs", "1"], capture_output=True, text=True,
                          timeout=120)
    assert done.returncode == 2, done.stderr
    # refused before the first layer: the G-code estimate exceeds the free space
    assert "MB are free where it goes" in done.stderr and "Traceback" not in done.stderr
    assert target.read_text() == OLD and leftovers(tiny_tmpfs) == []


def _die_on_third(state, item):
    if item == 2:
        os._exit(9)
    return item * state


def test_executor_turns_a_dead_worker_into_a_slice_error():
    with pytest.raises(SliceError, match="a worker process died") as info:
        list(map_ordered(_die_on_third, 10, range(8), jobs=2))
    assert "--jobs 1" in info.value.hint
    assert list(map_ordered(_die_on_third, 10, [0, 1, 3], jobs=2)) == [0, 10, 30]


def _layer_task_that_dies(job, index):
    if index == 1:
        os._exit(9)
    return _real_layer_task(job, index)


_real_layer_task = fgslice.pipeline._layer_task


def test_a_worker_killed_mid_slice_leaves_the_old_output(tmp_path, monkeypatch):
    target = tmp_path / "out.gcode"
    target.write_text(OLD)
    monkeypatch.setattr(fgslice.pipeline, "_layer_task", _layer_task_that_dies)
    with pytest.raises(SliceError, match="worker process died"):
        slice_to_gcode(box_design(), load_settings("marlin-mixing", {"strategy": 2}), target, jobs=2)
    assert target.read_text() == OLD and leftovers(tmp_path) == []


TALL = ('fgrade(["(1+sin(0.2*x)*cos(0.3*y))/2", "(1-sin(0.2*x)*cos(0.3*y))/2"], ["blue", "yellow"])'
        ' { cylinder(40, 120); }\n')


@pytest.fixture
def slow_slice(tmp_path):
    """Starts slow slices (:func:`_start_slow_slice`); kills what is left of them afterwards."""
    started = []

    yield lambda: _start_slow_slice(tmp_path, started)
    for proc in started:
        with contextlib.suppress(ProcessLookupError):
            os.killpg(proc.pid, signal.SIGKILL)
        proc.wait()


def _start_slow_slice(tmp_path, started):
    """A real ``fgslice slice`` of a part that takes several seconds, in its own process group;
    returns once it writes its temporary file."""
    design = tmp_path / "tall.vcad"
    design.write_text(TALL)
    target = tmp_path / "tall.gcode"
    target.write_text(OLD)
    proc = subprocess.Popen([FGSLICE, "slice", design, "-o", target, "--jobs", "2", "--strategy", "2"],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, start_new_session=True,
                            env={**os.environ, "PYTHONFAULTHANDLER": "1"})
    started.append(proc)
    deadline = time.monotonic() + 60
    while not leftovers(tmp_path):
        assert proc.poll() is None, proc.communicate()
        assert time.monotonic() < deadline, "the slice never started writing"
        time.sleep(0.05)
    return proc, target


@pytest.mark.slow
def test_ctrl_c_exits_130_and_keeps_the_old_output(tmp_path, slow_slice):
    proc, target = slow_slice()
    os.killpg(proc.pid, signal.SIGINT)
    try:
        out, err = proc.communicate(timeout=60)
    except subprocess.TimeoutExpired:
        proc.send_signal(signal.SIGABRT)
        pytest.fail("the interrupt was lost; where the slice was:\n" + proc.communicate()[1][-6000:])
    assert proc.returncode == 130, err
    assert "interrupted: no output file was written or changed" in err and "Traceback" not in err
    assert target.read_text() == OLD and leftovers(tmp_path) == []


@pytest.mark.slow
@pytest.mark.skipif(not Path("/proc/self/stat").exists(), reason="needs /proc to find the workers")
@pytest.mark.parametrize("signum", [signal.SIGTERM, signal.SIGHUP], ids=["SIGTERM", "SIGHUP"])
def test_termination_leaves_no_temporary_file_and_no_worker(tmp_path, slow_slice, signum):
    """As ``timeout`` or a closed terminal does: the signal goes to the slicer alone."""
    proc, target = slow_slice()
    deadline = time.monotonic() + 30
    while not (workers := _children(proc.pid)):
        assert proc.poll() is None and time.monotonic() < deadline, "no worker processes found"
        time.sleep(0.05)
    os.kill(proc.pid, signum)
    try:
        out, err = proc.communicate(timeout=60)
    except subprocess.TimeoutExpired:
        proc.send_signal(signal.SIGABRT)
        pytest.fail("the slice did not end; where it was:\n" + proc.communicate()[1][-6000:])
    assert proc.returncode == 128 + signum, err
    assert f"terminated ({signal.Signals(signum).name}): no output file was written or changed" in err
    assert "Traceback" not in err
    assert target.read_text() == OLD and leftovers(tmp_path) == []
    deadline = time.monotonic() + 10
    while alive := [pid for pid in workers if Path(f"/proc/{pid}").exists() and _state(pid) != "Z"]:
        assert time.monotonic() < deadline, f"workers still running: {alive}"
        time.sleep(0.05)


def _special_outputs(tmp_path):
    fifo = tmp_path / "pipe"
    os.mkfifo(fifo)
    return {"/dev/null": Path("/dev/null"), "/dev/zero": Path("/dev/zero"), "FIFO": fifo}


@pytest.mark.skipif(not Path("/dev/null").exists() or not hasattr(os, "mkfifo"), reason="needs /dev and FIFOs")
@pytest.mark.parametrize("name", ["/dev/null", "/dev/zero", "FIFO"])
def test_devices_and_fifos_are_refused_as_outputs(tmp_path, name):
    target = _special_outputs(tmp_path)[name]
    before = target.lstat()
    design = tmp_path / "box.vcad"
    design.write_text("cube(5);\n")
    for option in ("-o", "--stats"):
        args = ["slice", design, "-o", target] if option == "-o" else ["slice", design, "-o", tmp_path / "b.gcode",
                                                                        "--stats", target]
        result = CliRunner().invoke(main, [str(a) for a in args])
        assert result.exit_code == 2, result.output
        assert "fgslice only writes regular files" in result.output and "-o -" in result.output
        after = target.lstat()
        assert (after.st_mode, after.st_ino, after.st_rdev) == (before.st_mode, before.st_ino, before.st_rdev)
    assert leftovers(tmp_path) == []


def test_a_device_appearing_at_the_output_is_not_replaced(tmp_path):
    """Checked again just before the rename: an output that became a FIFO meanwhile."""
    target = tmp_path / "late"
    with pytest.raises(OutputError, match="FIFO"):
        with atomic_output(target) as handle:
            handle.write("G1 X1\n")
            os.mkfifo(target)
    assert stat_is_fifo(target) and leftovers(tmp_path) == []


def stat_is_fifo(path: Path) -> bool:
    import stat

    return stat.S_ISFIFO(path.lstat().st_mode)


def test_dash_writes_verified_gcode_to_stdout(tmp_path):
    design = tmp_path / "box.vcad"
    design.write_text("cube(5);\n")
    done = subprocess.run([FGSLICE, "slice", design, "-o", "-", "--set", "thumbnails="], cwd=tmp_path,
                          capture_output=True, timeout=120)
    assert done.returncode == 0, done.stderr
    assert done.stdout.startswith(b"; generated by fgslice") and b";LAYER_CHANGE" in done.stdout
    assert b"<stdout>: 25 layers" in done.stderr
    assert not (tmp_path / "-").exists() and sorted(p.name for p in tmp_path.iterdir()) == ["box.vcad"]
    (tmp_path / "copy.gcode").write_bytes(done.stdout)
    assert CliRunner().invoke(main, ["verify", str(tmp_path / "copy.gcode")]).exit_code == 0


def _children(pid: int) -> list[int]:
    found = []
    for stat in Path("/proc").glob("[0-9]*/stat"):
        try:
            fields = stat.read_text().rsplit(")", 1)[1].split()
        except OSError:
            continue
        if int(fields[1]) == pid:
            found.append(int(stat.parent.name))
    return found


@pytest.mark.slow
@pytest.mark.skipif(not Path("/proc/self/stat").exists(), reason="needs /proc to find the workers")
def test_killing_a_worker_of_a_real_slice_is_reported(tmp_path, slow_slice):
    proc, target = slow_slice()
    deadline = time.monotonic() + 30
    while not (workers := _children(proc.pid)):
        assert proc.poll() is None and time.monotonic() < deadline, "no worker processes found"
        time.sleep(0.05)
    os.kill(workers[0], signal.SIGKILL)
    out, err = proc.communicate(timeout=60)
    assert proc.returncode == 2, err
    assert "error: a worker process died while slicing" in err and "--jobs 1" in err and "Traceback" not in err
    assert target.read_text() == OLD and leftovers(tmp_path) == []


@pytest.mark.slow
@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="workers end with their parent on Linux")
def test_workers_end_when_the_slicer_is_killed(tmp_path, slow_slice):
    proc, target = slow_slice()
    deadline = time.monotonic() + 30
    while not (workers := _children(proc.pid)):
        assert proc.poll() is None and time.monotonic() < deadline, "no worker processes found"
        time.sleep(0.05)
    os.kill(proc.pid, signal.SIGKILL)
    proc.communicate(timeout=30)
    deadline = time.monotonic() + 10
    while alive := [pid for pid in workers if Path(f"/proc/{pid}").exists() and _state(pid) != "Z"]:
        assert time.monotonic() < deadline, f"orphaned workers still running: {alive}"
        time.sleep(0.05)
    assert target.read_text() == OLD


def _state(pid: int) -> str:
    try:
        return Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
    except OSError:
        return "gone"


def test_a_completed_slice_replaces_the_old_output(tmp_path):
    target = tmp_path / "out.gcode"
    target.write_text(OLD)
    slice_to_gcode(box_design(), load_settings(), target, jobs=1)
    assert read_gcode(target).e.sum() > 0 and leftovers(tmp_path) == []


@pytest.fixture
def ctrl_c_raises():
    """SIGINT raises KeyboardInterrupt in this process for the test (a test runner's
    worker may ignore it)."""
    previous = signal.signal(signal.SIGINT, signal.default_int_handler)
    yield
    signal.signal(signal.SIGINT, previous)


def _ctrl_c_after(make):
    """``make`` followed at once by a real Ctrl-C to this process."""
    def made_then_interrupted(*args, **kwargs):
        result = make(*args, **kwargs)
        os.kill(os.getpid(), signal.SIGINT)
        return result
    return made_then_interrupted


def test_ctrl_c_right_after_the_temporary_file_is_made_leaves_nothing(tmp_path, monkeypatch, ctrl_c_raises):
    import tempfile

    target = tmp_path / "out.gcode"
    target.write_text(OLD)
    monkeypatch.setattr(tempfile, "mkstemp", _ctrl_c_after(tempfile.mkstemp))
    with pytest.raises(KeyboardInterrupt):
        with atomic_output(target) as handle:
            handle.write("new")
    assert target.read_text() == OLD and leftovers(tmp_path) == []


def test_ctrl_c_as_a_slice_opens_its_output_leaves_nothing(tmp_path, monkeypatch, ctrl_c_raises):
    """The slice enters its output in an ExitStack: a Ctrl-C the moment the output is
    opened still finds the temporary file's cleanup registered."""
    target = tmp_path / "box.gcode"
    target.write_text(OLD)
    monkeypatch.setattr(fgslice.pipeline, "atomic_output", lambda *args: _InterruptedOnEntry(fgslice.output.atomic_output(*args)))
    with pytest.raises(KeyboardInterrupt) as raised:
        slice_to_gcode(box_design(), load_settings(None, {"colors": "2"}), target, jobs=1)
    assert target.read_text() == OLD and leftovers(tmp_path) == []  # checked while the traceback holds every frame
    del raised


class _InterruptedOnEntry:
    """A context manager whose entry is followed at once by a real Ctrl-C to this process."""

    def __init__(self, manager):
        self.manager = manager

    def __enter__(self):
        entered = self.manager.__enter__()
        os.kill(os.getpid(), signal.SIGINT)
        return entered

    def __exit__(self, *exc):
        return self.manager.__exit__(*exc)


@pytest.mark.parametrize("jobs", [1, 2])
def test_an_internal_error_on_a_layer_names_it_and_keeps_the_old_output(tmp_path, monkeypatch, jobs):
    design, out = tmp_path / "box.vcad", tmp_path / "box.gcode"
    design.write_text(BOX)
    out.write_text(OLD)

    def broken(regions, settings, bridges=None):
        if regions.index == 0:  # (later layers may repeat earlier ones without new paths)
            raise ValueError("no usable geometry")
        return strategy2_layer_paths(regions, settings)

    strategy2_layer_paths = fgslice.pipeline.strategy2.layer_paths
    monkeypatch.setattr(fgslice.pipeline.strategy2, "layer_paths", broken)
    result = CliRunner().invoke(main, ["slice", str(design), "-o", str(out), "--jobs", str(jobs)])
    assert result.exit_code == 2
    assert "layer 0 (z = 0.200 mm) could not be sliced: ValueError: no usable geometry" in result.output
    assert "Traceback" not in result.output
    assert out.read_text() == OLD and leftovers(tmp_path) == []


def test_an_unexpected_exception_is_a_short_message_unless_asked(tmp_path, monkeypatch):
    design = tmp_path / "box.vcad"
    design.write_text(BOX)

    def broken(*args, **kwargs):
        raise RuntimeError("unexpected state")

    monkeypatch.setattr(fgslice.design, "check_design", broken)
    result = CliRunner().invoke(main, ["check", str(design)])
    assert result.exit_code == 70
    assert "internal error in 'fgslice check': RuntimeError: unexpected state" in result.output
    assert "FGSLICE_TRACEBACK=1" in result.output and "Traceback" not in result.output
    monkeypatch.setenv("FGSLICE_TRACEBACK", "1")
    result = CliRunner().invoke(main, ["check", str(design)])
    assert isinstance(result.exception, RuntimeError)


@pytest.mark.parametrize("command", [["check"], ["slice", "-o", "-"]], ids=["check", "slice to stdout"])
def test_a_reader_that_stops_early_ends_the_command_quietly(tmp_path, command):
    """``fgslice check part.vcad | head -1``: as other Unix tools, exit 128 + SIGPIPE, no
    message. The reader is gone before the first write, so no pipe buffer hides the break."""
    design = tmp_path / "part.vcad"
    design.write_text("cube(10);\n")
    reader, writer = os.pipe()
    os.close(reader)
    try:
        proc = subprocess.run([str(FGSLICE), command[0], str(design), *command[1:]], stdout=writer,
                              stderr=subprocess.PIPE, text=True, cwd=tmp_path, timeout=120)
    finally:
        os.close(writer)
    assert proc.returncode == 128 + signal.SIGPIPE, proc.stderr
    assert "error" not in proc.stderr and "Traceback" not in proc.stderr
    assert sorted(p.name for p in tmp_path.iterdir()) == ["part.vcad"]
