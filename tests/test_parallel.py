"""The G-code is byte-identical whether layers run in one process, a local pool of two,
or on a Dask cluster of two worker processes — for both strategies, and for designs
whose fields are expression text or Python callables."""

from __future__ import annotations

import pytest

from fgslice.design import api
from fgslice.design.language import parse_design
from fgslice.pipeline import slice_to_gcode
from fgslice.settings import load_settings

pytest.importorskip("distributed")
pytestmark = pytest.mark.slow  # a two-process Dask cluster takes seconds to start

GRADED_DISC = """
fgrade(["x/24 + 0.5", "0.5 - x/24"], ["blue", "yellow"]) {
    translate(0, 0, 1) { cylinder(12, 2); }
}
"""


def _callable_design():
    """A box whose gradient is a Python function (pickled by value to Dask workers)."""
    return api.design(
        api.fgrade(
            [lambda x, y, z: 0.5 + y / 10, lambda x, y, z: 0.5 - y / 10],
            ["red", "blue"],
            api.translate((0, 0, 1), api.cube(8)),
        )
    )


def _slices(tmp_path, design, settings, address):
    """G-code bytes sliced serially, with two local workers, and on the cluster."""
    outputs = []
    for name, kwargs in (("serial", {"jobs": 1}), ("pool", {"jobs": 2}), ("dask", {"scheduler": address})):
        path = tmp_path / f"{name}.gcode"
        slice_to_gcode(design, settings, path, verify=False, **kwargs)
        outputs.append(path.read_bytes())
    return outputs


@pytest.mark.parametrize(
    "overrides",
    [
        {"strategy": "1", "colors": "4", "walls": "2", "layer_height": "0.4", "thumbnails": ""},
        {"strategy": "2", "colors": "6", "layer_height": "0.4", "thumbnails": ""},
    ],
    ids=["strategy1", "strategy2"],
)
def test_text_design_is_identical_on_every_executor(tmp_path, monkeypatch, dask_scheduler, overrides):
    monkeypatch.setenv("SOURCE_DATE_EPOCH", "1700000000")
    design = parse_design(GRADED_DISC)
    serial, pool, dask = _slices(tmp_path, design, load_settings(None, overrides), dask_scheduler)
    assert serial.count(b";LAYER_CHANGE") == 5
    assert serial.count(b";STATE:") >= 4
    assert pool == serial
    assert dask == serial


def test_callable_design_is_identical_on_dask(tmp_path, monkeypatch, dask_scheduler):
    monkeypatch.setenv("SOURCE_DATE_EPOCH", "1700000000")
    settings = load_settings(None, {"strategy": "2", "colors": "4", "layer_height": "0.4", "thumbnails": ""})
    serial, pool, dask = _slices(tmp_path, _callable_design(), settings, dask_scheduler)
    assert serial.count(b";LAYER_CHANGE") == 20
    assert pool == serial
    assert dask == serial
