"""The one-pass reading of plain move lines gives what the general word reader gives, for
valid, malformed and Unicode content, and when the text arrives in blocks split anywhere."""

import numpy as np
import pytest

from fgslice.machine.gcode_reader import iter_gcode_blocks, read_gcode
from fgslice.machine.verify import verify_gcode, verify_gcode_blocks
from fgslice.settings import load_settings

ARRAYS = ("start", "end", "e", "feed", "length", "line", "layer", "role", "state", "width", "unknown_lines")
NUMBERS = ["1", "-0", "+5", ".5", "-.25", "7.", "1234567", "12345678", "-0.0", "1.2.3", "-", ".", "1e3", "nan",
           "abc", "\u0661\u0662", "\u0663.5", "12\u00b9", "5;", "0.02702", "-300.125", "+.5", "99999.99"]


def random_moves(seed: int, n: int = 600) -> list[str]:
    """Move lines of every shape: plain, duplicated letters, many words, blank runs, tabs,
    leading or trailing blanks, CR line ends, lower case, arcs, odd numbers; plus state lines."""
    rng = np.random.default_rng(seed)
    lines = []
    for _ in range(n):
        if rng.random() < 0.15:
            lines.append(str(rng.choice([";TYPE:Perimeter", ";WIDTH:0.4", ";LAYER_CHANGE", "M83", "G92 E0", "G91",
                                         "G90", "M82", "; note", "", "T1", "M165 A0.25 B0.75"])))
            continue
        words = []
        for _ in range(rng.integers(0, 8)):
            number = (f"{rng.uniform(-300, 300):.{rng.integers(0, 6)}f}" if rng.random() < 0.8
                      else str(rng.choice(NUMBERS)))
            words.append(str(rng.choice(list("XYZEFXYEIJR" + ("xq" if rng.random() < 0.1 else "")))) + number)
        line = str(rng.choice(["G1", "G0", "G2", "G3", "g1"])) + "".join(
            str(rng.choice([" "] * 12 + ["\t", "  "])) + w for w in words)
        line = (" " if rng.random() < 0.03 else "") + line + str(rng.choice([""] * 30 + [" ", "\r"]))
        lines.append(line)
    return lines


def same_program(a, b) -> None:
    for name in ARRAYS:
        x, y = getattr(a, name), getattr(b, name)
        assert x.dtype == y.dtype and np.array_equal(x, y, equal_nan=True), name
        if x.dtype.kind == "f":
            assert np.array_equal(np.signbit(x), np.signbit(y)), name
    assert a.faults == b.faults and a.states == b.states and a.temperatures == b.temperatures


@pytest.mark.parametrize("seed", range(6))
def test_plain_lines_read_as_the_general_reader_reads_them(seed):
    """The same moves with a comment after each (which sends every line through the general
    word reader) give the same positions, extrusions, feeds and faults (bad numbers,
    Unicode digits, duplicated letters: the last one counts)."""
    lines = random_moves(seed)
    plain = "G1 X1 Y1\n" + "\n".join(lines) + "\n"
    commented = "G1 X1 Y1 ;c\n" + "\n".join(
        line.rstrip("\r") + " ;c" + ("\r" if line.endswith("\r") else "") if line.lstrip()[:1] in ("G", "g") else line
        for line in lines) + "\n"
    a, b = read_gcode(plain.encode()), read_gcode(commented.encode())
    same_program(a, b)
    assert a.faults  # the random lines hold bad numbers
    assert len(a.e) > 300


def test_plain_words_values_letters_and_faults():
    text = ("M83\nG1 X10.5 Y-2 E0.03 F1200\nG1 X1 X2 Y3\nG1 X\u0661\u0662 Y4\nG1 X5 Y6 Z0.2 E0.1 F900 I1 J2\n"
            "G1 X7 Y8 \nG1 X1.2.3 Y9\n")
    program = read_gcode(text.encode())
    assert program.end.tolist() == [[10.5, -2, 0], [2, 3, 0], [2, 4, 0], [5, 6, 0.2], [7, 8, 0.2], [7, 9, 0.2]]
    assert program.e.tolist() == [0.03, 0, 0, 0.1, 0, 0] and program.feed.tolist() == [1200] * 3 + [900] * 3
    assert [f.line for f in program.faults] == [4, 7]


def test_blocks_split_at_every_byte_give_the_whole_program():
    """Lines (and numbers) split across blocks at any byte are read and verified as the whole
    text is; the last line may lack its newline."""
    text = ("M83\nM104 S210\nG1 X10.5 Y20.25 E0.5 F1200\nG1 X\u0661 Y2\n;TYPE:Perimeter\n"
            "G1 X-1 Y300 E0.1\nG0 X5 Y5\nG1 X12345678 Y1 E0.2\nG1 X6 Y7 E9").encode()
    settings = load_settings("marlin-mixing")
    whole = read_gcode(text)
    faults = verify_gcode(text, settings)
    assert faults and whole.line_count == 9
    for cut in range(1, len(text)):
        for chunk_lines in (2, 1 << 16):
            blocks = [text[:cut], text[cut:]]
            parts = list(iter_gcode_blocks(blocks, chunk_lines=chunk_lines))
            assert np.concatenate([p.end for p in parts]).tolist() == whole.end.tolist()
            assert np.concatenate([p.e for p in parts]).tolist() == whole.e.tolist()
            assert sum((p.faults for p in parts), []) == whole.faults
            assert verify_gcode_blocks(blocks, settings, chunk_lines=chunk_lines) == faults
