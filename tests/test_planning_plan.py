"""LayerPlan pickling: paths travel as flat arrays and come back equal, prepared rows re-keyed."""

import copy
import pickle

import numpy as np
from conftest import same_steps

from fgslice.planning.plan import LayerPlan, Prepared, SetState
from fgslice.toolpaths.paths import Path, Role


def sample_plan(n=50):
    rng = np.random.default_rng(7)
    steps = []
    for k in range(n):
        if k % 7 == 0:
            steps.append(SetState(k % 5))
        pts = rng.uniform(0, 200, (2 + k % 9, 2))
        steps.append(Path(pts, list(Role)[k % len(Role)], k % 5 - 1, 0.4 + 0.01 * k, 0.2, closed=k % 2 == 0,
                          group=k // 10 if k % 3 else -1))
    steps.append(SetState(3))
    return LayerPlan(4, 1.0, 0.2, steps)


def test_pickle_round_trip_keeps_every_step():
    plan = sample_plan()
    back = pickle.loads(pickle.dumps(plan, protocol=pickle.HIGHEST_PROTOCOL))
    assert (back.index, back.z, back.height) == (4, 1.0, 0.2)
    same_steps(plan, back)
    same_steps(plan, copy.deepcopy(plan))
    empty = pickle.loads(pickle.dumps(LayerPlan(0, 0.2, 0.2, [SetState(1)])))
    assert empty.steps == [SetState(1)] and empty.paths == []


def test_paths_travel_as_one_array():
    plan = sample_plan(400)
    data = pickle.dumps(plan, protocol=pickle.HIGHEST_PROTOCOL)
    points = sum(p.points.nbytes for p in plan.paths)
    # a few numbers per path (attributes, exact length, step order), no per-array overhead
    assert len(data) < points + 64 * len(plan.paths)
    back = pickle.loads(data)
    bases = {id(p.points.base) for p in back.paths}
    assert len(bases) == 1


def test_prepared_rows_follow_their_paths():
    plan = sample_plan()
    paths = plan.paths
    extra = Path(np.array([[0.0, 0.0], [1.0, 1.0]]), Role.WIPE_TOWER, 1, 0.5, 0.2)
    plan.steps.insert(3, extra)
    plan.prepared = Prepared({p: 10 * k for k, p in enumerate(paths)}, {"payload": 1})
    back = pickle.loads(pickle.dumps(plan))
    same_steps(plan, back)
    rows = back.prepared.rows
    assert back.prepared.data == {"payload": 1}
    assert [rows.get(p, -1) for p in back.paths] == [plan.prepared.rows.get(p, -1) for p in plan.paths]
    assert rows.get(back.steps[3], -1) == -1


def test_pack_holds_the_same_steps_as_columns():
    plan = sample_plan()
    reference = copy.deepcopy(plan)
    packed = plan.pack()
    assert plan.packed is packed and plan.pack() is packed
    assert np.allclose(packed.lengths, [p.length for p in reference.paths], rtol=1e-12)
    data = pickle.dumps(plan)
    same_steps(reference, pickle.loads(data))
    same_steps(reference, plan)  # built again on access, columns dropped
    assert plan.packed is None


def test_pack_refuses_unknown_steps():
    class Marker(SetState):
        pass

    plan = LayerPlan(0, 0.2, 0.2, [Marker(1), SetState(2)])
    assert plan.pack() is None and plan.steps == [Marker(1), SetState(2)]
