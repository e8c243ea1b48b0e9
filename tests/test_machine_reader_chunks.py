"""Reading and verifying G-code in chunks gives what the whole program gives."""

import os

import numpy as np
import pytest

from fgslice.design import api
from fgslice.machine.gcode_reader import iter_gcode, read_gcode
from fgslice.machine.verify import verify_gcode
from fgslice.pipeline import slice_to_gcode
from fgslice.settings import load_settings

ARRAYS = ("start", "end", "e", "feed", "length", "line", "layer", "role", "state", "width", "unknown_lines")
EVENTS = ("temperatures", "tools", "flows", "mixes", "fans", "outputs", "faults")
SETTINGS = load_settings("marlin-mixing")


@pytest.fixture(scope="module")
def sliced(tmp_path_factory):
    """A ring with a radial gradient sliced for the foam profile (temperature and flow per state)."""
    ring = api.difference(api.cylinder(15, 2), api.cylinder(6, 2))
    design = api.design(api.fgrade(["rho/15", "1 - rho/15"], ["blue", "yellow"], ring))
    out = tmp_path_factory.mktemp("chunks") / "ring.gcode"
    slice_to_gcode(design, load_settings("foam-tpu", {"colors": "4"}), out, jobs=1)
    return out


def test_chunked_read_of_a_sliced_file_equals_the_whole_read(sliced):
    n_lines = sliced.read_text().count("\n")
    whole = read_gcode(sliced, chunk_lines=n_lines + 1)
    chunks = list(iter_gcode(sliced, chunk_lines=1000))
    assert len(chunks) == -(-n_lines // 1000) and chunks[-1].line_count == whole.line_count == n_lines
    for k, chunk in enumerate(chunks):
        assert chunk.states is whole.states or chunk.states is chunks[0].states
        assert ((chunk.line > k * 1000) & (chunk.line <= (k + 1) * 1000)).all()
    joined = read_gcode(sliced, chunk_lines=1000)
    for name in ARRAYS:
        assert np.array_equal(getattr(joined, name), getattr(whole, name), equal_nan=True), name
    for name in EVENTS:
        assert getattr(joined, name) == getattr(whole, name), name
    assert joined.states == whole.states and joined.roles == whole.roles and joined.layer_z == whole.layer_z
    assert len(whole.flows) > 4 and len(set(whole.state.tolist())) > 4 and whole.layer.max() == 9
    assert np.array_equal(joined.flow_of_moves(), whole.flow_of_moves())


def test_chunks_carry_modes_offsets_and_feed():
    text = "\n".join(["G91", "G1 X1 Y2 F600", "G1 X1", "M82", "G92 E5", "G1 X1 E6", "G90", "G1 X50 E7",
                      "M83", "G92 X0", "G1 Y1 E0.5", "G28 Y", "G1 X3"]) + "\n"
    whole = read_gcode(text)
    assert whole.end.tolist() == [[1, 2, 0], [2, 2, 0], [3, 2, 0], [50, 2, 0], [0, 1, 0], [3, 0, 0]]
    assert whole.e.tolist() == [0, 0, 1, 1, 0.5, 0] and whole.feed.tolist() == [600] * 6
    for n in (1, 2, 3, 5):
        joined = read_gcode(text, chunk_lines=n)
        for name in ARRAYS:
            assert np.array_equal(getattr(joined, name), getattr(whole, name), equal_nan=True), (n, name)


def test_chunks_without_moves_and_a_last_line_without_newline():
    text = "; header\n;LAYER_CHANGE\n;Z:0.2\n;TYPE:Perimeter\n;WIDTH:0.4\nM83\nG1 X1 Y1 E0.1\n\n\nG1 X2 E0.1"
    for n in (1, 2, 4, 100):
        chunks = list(iter_gcode(text, chunk_lines=n))
        p = read_gcode(text, chunk_lines=n)
        assert sum(len(c.e) for c in chunks) == 2 and p.line.tolist() == [7, 10] and p.line_count == 10
        assert p.layer.tolist() == [0, 0] and p.width.tolist() == [0.4, 0.4]
        assert [p.roles[r] for r in p.role] == ["Perimeter"] * 2 and p.layer_z == [0.2]


def cold_program():
    """Heats without waiting, extrudes (cold), waits, extrudes, then cools and extrudes."""
    lines = ["M104 S210", "G90", "M83", "G1 Z0.2 F600"]
    lines += [f"G1 X{10 + i} Y10 E0.1" for i in range(12)]  # lines 5-16: cold
    lines += ["M109 S210"]  # line 17
    lines += [f"G1 X{30 + i} Y10 E0.1" for i in range(10)]  # lines 18-27: heated
    lines += ["G91"]  # line 28: relative from here on
    lines += ["G1 X100 E0.1"] * 4  # lines 29-32: X 139, 239, 339 (outside the 255 mm bed from line 31)
    lines += ["M104 S150", "G1 X1 E0.1", "G1 Y1 E0.1"]  # lines 33-35: cooled, outside
    return "\n".join(lines) + "\n"


def test_verify_in_chunks_finds_the_same_faults_as_whole():
    text = cold_program()
    whole = verify_gcode(read_gcode(text), SETTINGS)
    assert [f.line for f in whole] == [5, 31, 34]
    assert "(12 moves, to line 16)" in whole[0].message
    assert "leaves the build volume" in whole[1].message and "(4 moves, to line 35)" in whole[1].message
    assert "nozzle at 150 C" in whole[2].message and "(2 moves, to line 35)" in whole[2].message
    for n in (1, 2, 3, 4, 7, 16, 17, 29, 33):
        assert verify_gcode(text, SETTINGS, chunk_lines=n) == whole, n


def test_verify_carries_temperatures_and_relative_mode_into_later_chunks():
    heat = ["M104 S210", "M109 S210", "G91", "M83", "G1 Z0.2"] + ["; padding"] * 20
    moves = [f"G1 X{10 if i == 0 else 0.5} Y0.1 E0.02" for i in range(300)]
    text = "\n".join(heat + moves) + "\n"
    assert verify_gcode(text, SETTINGS, chunk_lines=10) == []
    end = read_gcode(text, chunk_lines=10).end[-1]
    assert end == pytest.approx([10 + 0.5 * 299, 30, 0.2])
    faults = verify_gcode(text.replace("M109 S210", "M400"), SETTINGS, chunk_lines=10)
    assert [f.line for f in faults] == [26] and "(300 moves, to line 325)" in faults[0].message


def test_verify_of_a_file_followed_while_it_is_written(tmp_path, monkeypatch):
    """Blocks split anywhere (mid-line, mid-number) and a file read as it grows give the
    faults of the whole text."""
    from fgslice.machine.verify import follow_file, verify_gcode_blocks

    text = cold_program().encode()
    whole = verify_gcode(text, SETTINGS)
    rng = np.random.default_rng(5)
    cuts = np.sort(rng.choice(np.arange(1, len(text)), 12, replace=False)).tolist()
    blocks = [text[a:b] for a, b in zip([0, *cuts], [*cuts, len(text)])]
    assert verify_gcode_blocks(blocks, SETTINGS, chunk_lines=4) == whole

    path = tmp_path / "growing.gcode"
    handle = open(path, "wb")

    def writer():
        with handle:
            for block in blocks:
                handle.write(block)
                handle.flush()
                yield handle.tell()

    advised = []
    monkeypatch.setattr(os, "posix_fadvise", lambda fd, offset, length, advice: advised.append((offset, length, advice)))
    read = list(follow_file(path, writer()))
    assert b"".join(read) == text and len(read) > 3
    assert verify_gcode_blocks(read, SETTINGS) == whole
    # every block read is handed back for write-back, exactly the bytes read
    assert [(o, n) for o, n, _ in advised] == list(zip(np.cumsum([0, *map(len, read)])[:-1].tolist(), map(len, read)))
    assert {a for _, _, a in advised} == {os.POSIX_FADV_DONTNEED}


def test_numbers_short_and_long_read_as_float_does():
    rng = np.random.default_rng(3)
    texts = [f"{v:.{d}f}" for v, d in zip(rng.uniform(-2e6, 2e6, 3000) / 10.0 ** rng.integers(0, 7, 3000),
                                           rng.integers(0, 9, 3000))]
    texts = [t for t in texts if len(t) <= 16 and sum(c.isdigit() for c in t) <= 15]  # the reader's limits
    texts += ["0", "-0", "+5", ".5", "-.25", "7.", "1234567", "12345678", "-1234567.1234567", "0000000000001.5"]
    body = "".join(f"G1 X{t} Y1\n" for t in texts) + "G1 X1.2.3 Y1\nG1 X12345678.1.1 Y1\nG1 X-- Y1\n"
    program = read_gcode(("M83\n" + body).encode())
    n = len(texts)
    assert program.end[:n, 0].tolist() == [float(t) for t in texts]
    assert [f.line for f in program.faults] == [n + 2, n + 3, n + 4]


def test_plain_and_other_move_lines_read_alike():
    """Moves in the plain shape and the same moves written otherwise (comment, tab, lower
    case, extra blanks, long numbers, a word the reader ignores) give the same program."""
    rng = np.random.default_rng(5)
    xy = rng.uniform(0, 200, (400, 2)).round(3)
    e = rng.uniform(0, 0.2, 400).round(5)
    plain = "".join(f"G1 X{x:g} Y{y:g} E{v:g}\n" for (x, y), v in zip(xy, e))
    other = "".join(
        [f"G1 X{x:g} Y{y:g} E{v:g} ;c\n", f"G1\tX{x:g} Y{y:g} E{v:g}\n", f"g1 x{x:g} y{y:g} e{v:g}\n",
         f"G1  X{x:g} Y{y:g}  E{v:g}\n", f"G1 X{x:.7f} Y{y:g} E{v:.9f}\n", f"G1 X{x:g} S1 Y{y:g} E{v:g}\n"][i % 6]
        for i, ((x, y), v) in enumerate(zip(xy, e))
    )
    a, b = read_gcode(("M83\n" + plain).encode()), read_gcode(("M83\n" + other).encode())
    np.testing.assert_allclose(b.end, a.end, rtol=0, atol=1e-12)
    np.testing.assert_allclose(b.e, a.e, rtol=0, atol=1e-12)
    assert len(a.e) == 400 and not a.faults and not b.faults


def test_tool_and_state_numbers_in_other_digits_are_not_tool_changes():
    program = read_gcode("G1 X1 Y1\nT\u00b9\n;STATE:\u00b9 x\n;LAYER:\u00b2\nT2\n".encode())
    assert [ev.values["T"] for ev in program.tools] == [2.0]
    assert program.unknown_lines.tolist() == [2]
