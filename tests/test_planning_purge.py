"""Purge towers: placement, purge length per change, a tower on every layer, statistics."""

import pickle
from types import SimpleNamespace

import numpy as np
import pytest
import shapely
from conftest import same_steps

from fgslice.errors import SettingsError, SliceError
from fgslice.planning.order import order_layer
from fgslice.planning.plan import SetState
from fgslice.planning.purge import (
    PLA_DENSITY_G_CM3,
    TOWER_CLEARANCE_MM,
    PurgeStats,
    PurgeTower,
    insert_purges,
)
from fgslice.settings import Settings
from fgslice.toolpaths.paths import LayerPaths, Path, Role, bead_area

PALETTE = SimpleNamespace(centers=np.array([[0.125, 0.875], [0.375, 0.625], [0.625, 0.375], [0.875, 0.125]]))
PART = shapely.box(80, 80, 130, 120)
FOOTPRINT = shapely.buffer(PART, 3.5)  # part plus skirt


def layer_plans(n_layers, colors=(0, 1, 2, 3)):
    """Order real layers: each color owns a vertical band of infill lines of the part."""
    plans, position = [], np.array([0.0, 0.0])
    for k in range(n_layers):
        paths = [Path(np.array([[80.0 + 12.5 * c + 0.4 * i, 80.0], [80.0 + 12.5 * c + 0.4 * i, 120.0]]),
                      Role.SOLID_INFILL, c, 0.4, 0.2) for c in colors for i in range(30)]
        if k == 0:
            paths.append(Path(np.array(shapely.buffer(PART, 3).exterior.coords[:-1]), Role.SKIRT, -1, 0.4, 0.2, closed=True))
        order = np.array(colors) if k % 2 == 0 else np.array(colors)[::-1]
        plan = order_layer(LayerPaths(k, 0.2 * (k + 1), 0.2, paths), order, position, "walls_first")
        position = plan.paths[-1].end
        plans.append(plan)
    return plans


def purges_per_change(plans):
    """Total WIPE_TOWER length following each SetState, and the state changes seen."""
    out, state = [], None
    for plan in plans:
        steps = plan.steps
        for i, step in enumerate(steps):
            if isinstance(step, SetState):
                length = 0.0
                for nxt in steps[i + 1:]:
                    if not isinstance(nxt, Path) or nxt.role is not Role.WIPE_TOWER:
                        break
                    assert nxt.color == step.color
                    length += nxt.length
                out.append((plan.index, state, step.color, length))
                state = step.color
    return out


def test_each_change_purges_the_melt_volume_and_unchanged_states_purge_nothing():
    settings = Settings(melt_volume_mm3=20.0)
    plans = layer_plans(6)
    tower = PurgeTower.plan(FOOTPRINT, settings, changes_per_layer=4, n_layers=6)
    stats = PurgeStats()
    out = list(insert_purges(iter(plans), tower, settings, PALETTE, stats))
    expected = 20.0 / (0.2 * (0.4 - 0.2) + np.pi * 0.2**2 / 4)
    records = purges_per_change(out)
    changed = [r for r in records if r[1] != r[2]]
    same = [r for r in records if r[1] == r[2]]
    assert all(r[3] == pytest.approx(expected, rel=0.05) for r in changed)
    # Reversed order on odd layers: the first color of layer k+1 is the last of layer k.
    assert len(same) == 5 and all(r[3] == 0.0 for r in same)
    assert stats.changes == len(changed) == 4 + 5 * 3
    assert stats.purge_mm3 == pytest.approx(stats.changes * 20.0, rel=0.05)
    assert stats.purge_g == pytest.approx(stats.purge_mm3 * PLA_DENSITY_G_CM3 / 1000)
    part_mm3 = sum(p.length * bead_area(p.width, p.height) for plan in plans for p in plan.paths)
    assert stats.extruded_mm3 == pytest.approx(part_mm3 + stats.tower_mm3, rel=1e-9)
    assert 0 < stats.waste_share < 1
    assert stats.waste_share == pytest.approx(stats.tower_mm3 / stats.extruded_mm3)
    # The part's own paths are untouched and in the same order.
    for before, after in zip(plans, out):
        assert [p for p in after.paths if p.role is not Role.WIPE_TOWER] == before.paths


def test_plans_received_as_columns_get_the_same_tower_without_building_their_paths():
    settings = Settings(melt_volume_mm3=20.0)
    plans = layer_plans(4)
    tower = PurgeTower.plan(FOOTPRINT, settings, changes_per_layer=4, n_layers=4)
    plain_stats, packed_stats = PurgeStats(), PurgeStats()
    plain = list(insert_purges(iter(plans), tower, settings, PALETTE, plain_stats))
    received = [pickle.loads(pickle.dumps(plan)) for plan in plans]  # as from a worker
    packed = list(insert_purges(iter(received), tower, settings, PALETTE, packed_stats))
    assert all(plan.packed is not None for plan in packed)  # no path was built on the way
    assert packed_stats.extruded_mm3 == pytest.approx(plain_stats.extruded_mm3, rel=1e-12)
    assert (packed_stats.changes, packed_stats.purge_mm3) == (plain_stats.changes, plain_stats.purge_mm3)
    for a, b in zip(plain, packed):
        same_steps(a, b)


def test_tower_is_on_the_bed_clear_of_the_part_and_printed_on_every_layer():
    settings = Settings()
    tower = PurgeTower.plan(FOOTPRINT, settings, changes_per_layer=4, n_layers=5)
    box = tower.footprint
    assert shapely.distance(box, FOOTPRINT) >= TOWER_CLEARANCE_MM - 1e-6
    assert shapely.within(box, shapely.box(0, 0, settings.bed_x, settings.bed_y))
    # Sized so four full purges fit: rows of lines at spacing w cover 4 L w of area.
    assert box.area >= 4 * tower.purge_mm * settings.bead_width
    out = list(insert_purges(iter(layer_plans(5)), tower, settings, PALETTE))
    for plan in out:
        tower_paths = [p for p in plan.paths if p.role is Role.WIPE_TOWER]
        printed = shapely.union_all(shapely.buffer([shapely.LineString(p.vertices) for p in tower_paths], 0.2,
                                                  cap_style="square", join_style="mitre"))
        assert shapely.within(printed, box.buffer(1e-6))
        # Perimeter plus fill: the whole box outline is printed and lines reach every part of it.
        assert printed.area > 0.25 * box.area
        assert shapely.buffer(printed, 2.5).covers(box)
        assert shapely.within(box.exterior, printed.buffer(1e-6))


def test_purge_off_passes_plans_through():
    plans = layer_plans(2)
    settings = Settings(purge=False)
    out = list(insert_purges(iter(plans), None, settings, PALETTE))
    assert all(a is b for a, b in zip(out, plans))


def test_placement_errors_are_explained():
    with pytest.raises(SliceError, match="overlaps the part") as err:
        PurgeTower.plan(FOOTPRINT, Settings(purge_tower_x=100, purge_tower_y=100), 4, 10)
    assert "purge_tower_x" in err.value.hint
    with pytest.raises(SliceError, match="leaves the 220 x 220 mm bed"):
        PurgeTower.plan(FOOTPRINT, Settings(purge_tower_x=215, purge_tower_y=100), 4, 10)
    placed = PurgeTower.plan(FOOTPRINT, Settings(purge_tower_x=40, purge_tower_y=40), 2, 10)
    assert placed.footprint.centroid.equals_exact(shapely.Point(40, 40), 1e-9)
    with pytest.raises(SliceError, match="no room") as err:
        PurgeTower.plan(shapely.box(5, 5, 215, 215), Settings(), 16, 10)
    assert "purge=false" in err.value.hint
    with pytest.raises(SettingsError, match="together"):
        PurgeTower.plan(FOOTPRINT, Settings(purge_tower_x=40), 2, 10)


def test_a_layer_with_more_changes_than_planned_is_refused():
    tower = PurgeTower.plan(FOOTPRINT, Settings(), changes_per_layer=2, n_layers=3)
    with pytest.raises(ValueError, match="sized for 2"):
        list(insert_purges(iter(layer_plans(1)), tower, Settings(), PALETTE))


def test_layers_with_the_same_changes_share_their_tower_paths():
    settings = Settings(melt_volume_mm3=20.0)
    tower = PurgeTower.plan(FOOTPRINT, settings, changes_per_layer=4, n_layers=6)
    stats = PurgeStats()
    out = list(insert_purges(iter(layer_plans(6)), tower, settings, PALETTE, stats))
    tower_paths = [[p for p in plan.paths if p.role is Role.WIPE_TOWER] for plan in out]
    # layers 2 and 4 start in the same state and change through the same colors
    assert len(tower_paths[2]) == len(tower_paths[4]) > 1
    assert all(a is b for a, b in zip(tower_paths[2], tower_paths[4]))
    volume = sum(p.length * bead_area(p.width, p.height) for paths in tower_paths for p in paths)
    assert stats.tower_mm3 == pytest.approx(volume, rel=1e-12)


def layer_plans_by_layer(colors_of_layers):
    """Like :func:`layer_plans`, with the colors of each layer given (traversal order)."""
    plans, position = [], np.array([0.0, 0.0])
    for k, colors in enumerate(colors_of_layers):
        paths = [Path(np.array([[80.0 + 12.5 * c + 0.4 * i, 80.0], [80.0 + 12.5 * c + 0.4 * i, 120.0]]),
                      Role.SOLID_INFILL, c, 0.4, 0.2) for c in colors for i in range(30)]
        plan = order_layer(LayerPaths(k, 0.2 * (k + 1), 0.2, paths), np.array(colors), position, "walls_first")
        position = plan.paths[-1].end
        plans.append(plan)
    return plans


def tower_layers(plans):
    return [plan.index for plan in plans if any(p.role is Role.WIPE_TOWER for p in plan.paths)]


def test_the_tower_ends_at_the_last_layer_with_a_change():
    settings = Settings(melt_volume_mm3=20.0)
    # changes on layers 0-2 (and the first color of the print), then color 1 to the top
    plans = layer_plans_by_layer([(0, 1), (1, 2), (2, 1)] + [(1,)] * 5)
    tower = PurgeTower.plan(FOOTPRINT, settings, changes_per_layer=2, n_layers=8)
    stats = PurgeStats()
    out = list(insert_purges(iter(plans), tower, settings, PALETTE, stats))
    assert [plan.index for plan in out] == list(range(8))
    assert tower_layers(out) == [0, 1, 2]
    for before, after in zip(plans[3:], out[3:]):
        assert after.paths == before.paths
    assert stats.changes == 4  # None -> 0, 0 -> 1, 1 -> 2, 2 -> 1
    part_mm3 = sum(p.length * bead_area(p.width, p.height) for plan in plans for p in plan.paths)
    assert stats.extruded_mm3 == pytest.approx(part_mm3 + stats.tower_mm3, rel=1e-9)


def test_layers_without_a_change_below_a_later_change_carry_the_tower():
    settings = Settings(melt_volume_mm3=20.0)
    plans = layer_plans_by_layer([(0,)] * 4 + [(0, 3)])
    tower = PurgeTower.plan(FOOTPRINT, settings, changes_per_layer=2, n_layers=5)
    out = list(insert_purges(iter(plans), tower, settings, PALETTE))
    assert tower_layers(out) == [0, 1, 2, 3, 4]  # the tower stands on the bed, not on air
    records = [r for r in purges_per_change(out) if r[1] != r[2]]
    assert [(r[0], r[1], r[2]) for r in records] == [(0, None, 0), (4, 0, 3)]
    assert all(r[3] > 0 for r in records)


def test_a_print_that_never_changes_state_has_no_tower():
    settings = Settings(melt_volume_mm3=20.0)
    plans = layer_plans_by_layer([(2,)] * 6)
    tower = PurgeTower.plan(FOOTPRINT, settings, changes_per_layer=1, n_layers=6)
    stats = PurgeStats()
    out = list(insert_purges(iter(plans), tower, settings, PALETTE, stats))
    assert tower_layers(out) == []
    assert (stats.tower_mm3, stats.changes) == (0.0, 0)
    assert all(a is b for a, b in zip(out, plans))


def walls_and_infill_plans(n_layers, colors=(0, 1, 2, 3), infill_lines=10):
    """Layers where each color owns a band with a wall loop and ``infill_lines`` sparse lines."""
    plans, position = [], np.array([0.0, 0.0])
    for k in range(n_layers):
        paths = []
        for c in colors:
            x0 = 80.0 + 12.5 * c
            paths.append(Path(np.array([[x0, 80.0], [x0 + 12, 80.0], [x0 + 12, 120.0], [x0, 120.0]]),
                              Role.EXTERNAL_PERIMETER, c, 0.4, 0.2, closed=True))
            paths += [Path(np.array([[x0 + 1 + i, 81.0], [x0 + 1 + i, 119.0]]), Role.INTERNAL_INFILL, c, 0.4, 0.2)
                      for i in range(infill_lines)]
        order = np.array(colors) if k % 2 == 0 else np.array(colors)[::-1]
        plan = order_layer(LayerPaths(k, 0.2 * (k + 1), 0.2, paths), order, position, "walls_first")
        position = plan.paths[-1].end
        plans.append(plan)
    return plans


@pytest.mark.parametrize("infill_lines", [2, 10])
def test_purge_into_infill_prints_the_new_colors_infill_first_and_the_tower_only_what_is_left(infill_lines):
    from fgslice.planning.purge import _unsettled_mm3

    settings = Settings(melt_volume_mm3=20.0, purge_into_infill=True)
    plans = walls_and_infill_plans(4, infill_lines=infill_lines)
    tower = PurgeTower.plan(FOOTPRINT, settings, changes_per_layer=4, n_layers=4)
    stats = PurgeStats()
    out = list(insert_purges(iter(plans), tower, settings, PALETTE, stats))
    area = settings.bead_area
    since, state = 0.0, None
    for before, after in zip(plans, out):
        # the same part paths, only reordered within each color
        assert sorted(map(id, after.paths)) == sorted(map(id, before.paths + [p for p in after.paths if p.role is Role.WIPE_TOWER]))
        steps = after.steps
        marks = [i for i, s in enumerate(steps) if isinstance(s, SetState)]
        since += sum(p.length * area for p in steps[: marks[0]] if isinstance(p, Path) and p.role is not Role.WIPE_TOWER)
        for i, j in zip(marks, marks[1:] + [len(steps)]):
            group = steps[i + 1 : j]
            color = steps[i].color
            roles = [p.role for p in group]
            if color == state:
                assert Role.WIPE_TOWER not in roles
                since += sum(p.length * area for p in group)
                continue
            n_infill = roles.count(Role.INTERNAL_INFILL)
            assert roles[:n_infill] == [Role.INTERNAL_INFILL] * n_infill  # the new color's infill first
            poured = sum(p.length * area for p in group[:n_infill])
            tower_mm3 = sum(p.length * area for p in group if p.role is Role.WIPE_TOWER)
            expected = min(max(0.0, 20.0 + _unsettled_mm3(since, settings) - poured), 20.0)
            assert tower_mm3 == pytest.approx(expected, rel=1e-6, abs=1e-6)
            rest = roles[n_infill + (tower_mm3 > 0):]
            assert rest and all(r is Role.EXTERNAL_PERIMETER for r in rest)  # then walls
            assert all(p.color == color for p in group if p.role is not Role.WIPE_TOWER)
            since = sum(p.length * area for p in group)  # the tower purge included
            state = color
    part_mm3 = sum(p.length * bead_area(p.width, p.height) for plan in plans for p in plan.paths)
    assert stats.extruded_mm3 == pytest.approx(part_mm3 + stats.tower_mm3, rel=1e-9)
    plain = PurgeStats()
    list(insert_purges(iter(walls_and_infill_plans(4, infill_lines=infill_lines)), tower,
                       Settings(melt_volume_mm3=20.0), PALETTE, plain))
    assert stats.purge_mm3 < plain.purge_mm3
    if infill_lines == 10:  # 10 lines of 38 mm (27 mm^3) take every purge: no tower at all
        assert stats.tower_mm3 == 0.0 and tower_layers(out) == []
    else:
        assert tower_layers(out) == [0, 1, 2, 3]


def test_unsettled_purge_grows_with_a_short_previous_run():
    from fgslice.planning.purge import _unsettled_mm3

    settings = Settings(melt_volume_mm3=68.5, mixing_share=0.3)
    v_mix = 0.3 * 68.5
    assert _unsettled_mm3(0.0, settings) == pytest.approx(v_mix * np.log(2))
    assert _unsettled_mm3(0.7 * 68.5, settings) == pytest.approx(v_mix * np.log(2))
    assert _unsettled_mm3(68.5 + 10 * v_mix, settings) == pytest.approx(v_mix * np.exp(-11), rel=1e-3)
    assert _unsettled_mm3(100.0, Settings(mixing_share=0.0)) == 0.0


def test_purges_into_infill_leave_no_row_of_the_tower_empty():
    """Shortened purges are laid one after another from the first row and the sparse
    fill starts at the next free row: every row of the tower gets a line on every layer."""
    settings = Settings(melt_volume_mm3=20.0, purge_into_infill=True)
    tower = PurgeTower.plan(FOOTPRINT, settings, changes_per_layer=4, n_layers=4)
    out = list(insert_purges(iter(walls_and_infill_plans(4, infill_lines=2)), tower, settings, PALETTE))
    w = tower.line_width
    for plan in out:
        steps = plan.steps
        first = next(i for i, step in enumerate(steps) if isinstance(step, SetState))
        tower_paths = [(i, p) for i, p in enumerate(steps) if isinstance(p, Path) and p.role is Role.WIPE_TOWER]
        purges = [p for i, p in tower_paths if i > first]  # the base comes before the first SetState
        fill = [p for i, p in tower_paths if i < first and not p.closed]
        rows = np.round((np.concatenate([p.points[:, 1] for p in purges]) - tower.y0 - w) / w).astype(int)
        used = np.unique(rows)
        assert len(purges) >= 3 and used[0] == 0
        assert np.array_equal(used, np.arange(used[-1] + 1))  # contiguous from the first row
        (sparse,) = fill
        assert sparse.points[:, 1].min() == pytest.approx(tower.y0 + w + w * (used[-1] + 1))
        assert sparse.points[:, 1].max() == pytest.approx(tower.y0 + w * tower.rows)
