"""OpenVCAD 3's DICOM volumes: a CT series read with pydicom, sampled trilinearly, as an
attribute that drives the machine through a converter."""

from __future__ import annotations

import re
import textwrap
from datetime import datetime, timezone

import numpy as np
import pytest

from fgslice.compat.script import load_script
from fgslice.design.attributes import attribute_fields
from fgslice.design.volumes import load_dicom_series
from fgslice.errors import FgsliceError
from fgslice.machine.gcode_reader import read_gcode
from fgslice.pipeline import slice_to_gcode
from fgslice.settings import load_settings

ORIGIN = np.array([-20.0, -8.0, 5.0])  # the first voxel's centre, mm
SPACING = np.array([2.0, 1.6, 1.25])  # x (columns), y (rows), z (slices), mm
SHAPE = (5, 11, 21)  # slices, rows, columns


def _hu(x, y, z):
    """The series' Hounsfield units: linear, so trilinear sampling is exact inside."""
    return 40.0 * x + 5.0 * y + 60.0 * (z - 5.0) - 200.0


def _write_series(folder, orientation=(1, 0, 0, 0, 1, 0), positions=None):
    from pydicom.dataset import Dataset, FileMetaDataset
    from pydicom.uid import CTImageStorage, ExplicitVRLittleEndian, generate_uid

    folder.mkdir()
    k, j, i = np.indices(SHAPE)
    hu = _hu(ORIGIN[0] + i * SPACING[0], ORIGIN[1] + j * SPACING[1], ORIGIN[2] + k * SPACING[2])
    stored = np.round((hu + 2048.0) / 2.0).astype(np.uint16)  # slope 2, intercept -2048
    for n in range(SHAPE[0]):
        meta = FileMetaDataset()
        meta.MediaStorageSOPClassUID = CTImageStorage
        meta.MediaStorageSOPInstanceUID = generate_uid()
        meta.TransferSyntaxUID = ExplicitVRLittleEndian
        ds = Dataset()
        ds.file_meta = meta
        ds.SOPClassUID, ds.SOPInstanceUID = CTImageStorage, meta.MediaStorageSOPInstanceUID
        ds.Modality = "CT"
        ds.Rows, ds.Columns = SHAPE[1], SHAPE[2]
        ds.BitsAllocated, ds.BitsStored, ds.HighBit, ds.PixelRepresentation = 16, 16, 15, 0
        ds.SamplesPerPixel, ds.PhotometricInterpretation = 1, "MONOCHROME2"
        ds.PixelSpacing = [float(SPACING[1]), float(SPACING[0])]
        z = ORIGIN[2] + n * SPACING[2] if positions is None else positions[n]
        ds.ImagePositionPatient = [float(ORIGIN[0]), float(ORIGIN[1]), float(z)]
        ds.ImageOrientationPatient = list(orientation)
        ds.RescaleSlope, ds.RescaleIntercept = 2, -2048
        ds.PixelData = stored[n].tobytes()
        ds.save_as(folder / f"slice{SHAPE[0] - n:03d}.dcm", enforce_file_format=True)  # written in reverse order
    (folder / "notes.txt").write_text("not a slice\n")
    return folder


def test_a_dicom_series_is_its_rescaled_values_on_a_trilinear_grid(tmp_path):
    volume = load_dicom_series(_write_series(tmp_path / "ct"))
    lo, hi = volume.bounds()
    np.testing.assert_allclose(lo, ORIGIN - SPACING / 2)
    np.testing.assert_allclose(hi, ORIGIN + SPACING * (np.array(SHAPE[::-1]) - 0.5))
    rng = np.random.default_rng(1)
    inner_lo, inner_hi = ORIGIN, ORIGIN + SPACING * (np.array(SHAPE[::-1]) - 1)
    x, y, z = (rng.uniform(inner_lo[a], inner_hi[a], 200) for a in range(3))
    np.testing.assert_allclose(volume(x, y, z), _hu(x, y, z), atol=1.0)  # stored in steps of 2 HU
    # beyond the centres the faces are held flat
    np.testing.assert_allclose(volume(np.array([hi[0]]), np.array([0.0]), np.array([inner_lo[2]])),
                               _hu(inner_hi[0], 0.0, inner_lo[2]), atol=1.0)


def test_a_ct_scan_s_hu_drives_the_nozzle_temperature_through_a_converter(tmp_path):
    _write_series(tmp_path / "ct")
    script = tmp_path / "scan.py"
    script.write_text(textwrap.dedent("""
        import pyvcad as pv
        volume = pv.DICOMLoader("ct").as_volume()
        solid = pv.RectPrism.FromMinAndMax(*volume.bounding_box())
        solid.set_attribute(pv.DefaultAttributes.HU, pv.FloatAttribute(volume))
        hu = pv.FloatAttribute()
        hu.set_volume(volume)
        assert abs(volume.sample(0, 0, 5) - (-200)) <= 1 and abs(hu.sample(0, 0, 5, 0) - (-200)) <= 1
        to_t = pv.ExpressionConverter(["hu"], ["temperature"], ["clamp(195, 210 + hu / 100, 230)"])
        root = pv.AttributeModifier(to_t, solid)
    """))
    design = load_script(script)
    x = np.array([-18.0, 0.0, 18.0])
    np.testing.assert_allclose(attribute_fields(design).values("hu", x, 0 * x, 0 * x + 5), _hu(x, 0, 5), atol=1.0)
    settings = load_settings("foam-lwpla", {"layer_height": "0.3"})
    out = tmp_path / "scan.gcode"
    result = slice_to_gcode(design, settings, out, jobs=1, stamp=datetime(2026, 1, 1, tzinfo=timezone.utc))
    program = read_gcode(out)
    printed = (program.e > 0) & (program.length > 0) & (program.layer == 3)
    mid = (program.start + program.end)[printed] / 2 - np.array(result.stats["placement_offset"])
    designed = np.clip(210 + _hu(mid[:, 0], mid[:, 1], mid[:, 2] - 0.15) / 100, 195, 230)
    commanded = np.array([program.states[s].temperature for s in program.state[printed]])
    assert np.abs(commanded - designed).max() <= settings.temperature_step / 2 + 0.5
    assert commanded.max() - commanded.min() >= 10


@pytest.mark.parametrize("kind,message", [
    ("tilted", "is not an axial slice"),
    ("uneven", "are not evenly spaced along Z"),
    ("empty", "no DICOM slice with pixel data"),
])
def test_series_fgslice_cannot_place_are_refused_with_the_reason(tmp_path, kind, message):
    folder = tmp_path / "ct"
    if kind == "tilted":
        _write_series(folder, orientation=(1, 0, 0, 0, 0, -1))
    elif kind == "uneven":
        _write_series(folder, positions=[5.0, 6.0, 8.0, 9.0, 10.0])
    else:
        folder.mkdir()
        (folder / "readme.txt").write_text("no slices\n")
    with pytest.raises(FgsliceError, match=re.escape(message)):
        load_dicom_series(folder)
