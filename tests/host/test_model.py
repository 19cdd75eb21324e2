"""The robot model: tables, the pose update against the reference vectors, and the effects."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from pac_host.errors import InputError
from pac_host.model import (
    Effect,
    GaitTable,
    integrate,
    load_table,
    measured_table,
    parse_effect,
    resolve_table,
    rollout,
    save_table,
    shifted_table,
    step_moves,
)
from pac_host.model.effects import effective_rows
from pac_host.model.kinematics import (
    complex_moves,
    heading_rotation,
    loop_moves,
    repeated_moves,
)


def _cases(data_dir):
    return json.loads((data_dir / "kinematics.json").read_text())["cases"]


def test_kinematics_vectors_reproduced_to_1e6(data_dir):
    cases = _cases(data_dir)
    assert len(cases) >= 7
    for case in cases:
        table = resolve_table(case["table"])
        poses = rollout(table.rows, case["start_pose"], case["gait_cycles"])
        np.testing.assert_allclose(poses[0], case["start_pose"], atol=1e-12)
        np.testing.assert_allclose(poses[1:], case["poses"], atol=1e-6, rtol=0,
                                   err_msg=case["name"])


def test_kinematics_copy_equals_upstream(data_dir, upstream_vectors):
    """The repository's copy of the kinematics vectors is the design's reference file, unchanged."""
    upstream = upstream_vectors / "kinematics.json"
    if not upstream.is_file():
        pytest.skip(f"no upstream reference vectors at {upstream} (a plain clone)")
    copy = json.loads((data_dir / "kinematics.json").read_text())
    assert copy == json.loads(upstream.read_text())


def test_pose_update_formula_by_hand():
    # heading 0 (+y): F goes to +y, T (right) goes to +x; then the heading turns
    p = integrate(np.array([10.0, 20.0, 0.0]), np.array([[5.0, 2.0, 30.0], [4.0, 0.0, 0.0]]))
    assert p[1].tolist() == pytest.approx([12.0, 25.0, 30.0])
    h = math.radians(30)
    assert p[2].tolist() == pytest.approx([12 + 4 * math.sin(h), 25 + 4 * math.cos(h), 30.0])


def test_a_loops_net_move_is_where_one_pass_of_it_walks_to():
    """loop_moves composes repeated_moves; one pass of the loop walked gait cycle by gait cycle
    (rollout) must end where the net move, applied to the start pose, puts it."""
    rng = np.random.default_rng(3)
    for rows in (measured_table().rows, shifted_table().rows):
        repeated = repeated_moves(complex_moves(rows), 63)
        for _ in range(20):
            genes = np.stack((rng.integers(0, 32, 9), rng.integers(0, 64, 9)), axis=-1)
            ids = np.repeat(genes[:, 0], genes[:, 1])
            start = np.array([45.0, 30.0, rng.uniform(-180, 180)])
            end = rollout(rows, start, ids)[-1]
            d, rot = loop_moves(genes, repeated)
            q0 = heading_rotation(start[2])
            p = start[0] + 1j * start[1] + q0 * d
            assert (p.real, p.imag) == pytest.approx((end[0], end[1]), abs=1e-9)
            assert q0 * rot == pytest.approx(heading_rotation(end[2]), abs=1e-12)


def test_heading_is_not_wrapped():
    p = rollout(measured_table().rows, (45, 30, 90), [0] * 20)
    assert p[-1, 2] == pytest.approx(90 + 20 * 24.3)


def test_shifted_table_is_one_strength_weaker():
    m, s = measured_table().rows, shifted_table().rows
    for side in (0, 16):
        for n in range(15):
            assert s[side + n].tolist() == m[side + n + 1].tolist()
        assert s[side + 15].tolist() == m[side + 15].tolist()
    assert not any(np.array_equal(m[0], r) for r in s)  # the maximum turn is gone


def test_table_json_round_trip(tmp_path):
    t = shifted_table().with_effects([Effect("yaw_bias", {"delta": 1.5})])
    save_table(t, tmp_path / "t.json")
    back = load_table(tmp_path / "t.json")
    assert np.array_equal(back.rows, t.rows)
    assert back.effects == t.effects


@pytest.mark.parametrize(
    "mutate, message",
    [
        (lambda d: d.update(format="other"), "'format' must be"),
        (lambda d: d["cycles"].pop(), "ids missing: [31]"),
        (lambda d: d["cycles"].append(dict(d["cycles"][0])), "appears twice"),
        (lambda d: d["cycles"][3].update(F="x"), "cycles[3] (id 3).F must be a finite number"),
        (lambda d: d["cycles"][3].update(id=40), "id must be an integer 0..31"),
        (lambda d: d.update(effects=[{"name": "wobble", "params": {}}]), "unknown effect 'wobble'"),
        (lambda d: d.update(effects=[{"name": "yaw_bias", "params": {"d": 1}}]),
         "parameters must be"),
    ],
)
def test_table_validation_names_the_problem(tmp_path, mutate, message):
    doc = measured_table().to_json()
    mutate(doc)
    path = tmp_path / "bad.json"
    path.write_text(json.dumps(doc))
    with pytest.raises(InputError) as e:
        load_table(path)
    assert message in str(e.value)


def test_table_file_not_json(tmp_path):
    (tmp_path / "t.json").write_text("{nope")
    with pytest.raises(InputError, match="not valid JSON"):
        load_table(tmp_path / "t.json")
    with pytest.raises(InputError, match="cannot read"):
        load_table(tmp_path / "missing.json")


def test_nan_rows_rejected():
    rows = measured_table().rows.copy()
    rows[4, 1] = np.nan
    with pytest.raises(InputError, match="NaN"):
        GaitTable(rows)


# --- effects: each definition of DESIGN.md section 3 checked on a small case -------------------

M = measured_table().rows


def _moves(ids, *effects, n0=0, prev=None):
    body, world = step_moves(M, np.array(ids), list(effects), n0, prev)
    return body, world


def test_turn_shift_clamps_within_side():
    eff = effective_rows(M, [Effect("turn_shift", {"k": 3})])
    assert eff[0].tolist() == M[3].tolist()
    assert eff[14].tolist() == M[15].tolist()  # clamped at 15
    assert eff[16 + 2].tolist() == M[16 + 5].tolist()
    neg = effective_rows(M, [Effect("turn_shift", {"k": -2})])
    assert neg[1].tolist() == M[0].tolist()


def test_table_level_effects():
    b, _ = _moves([3], Effect("turn_scale", {"c": 0.5}))
    assert b[0].tolist() == pytest.approx([M[3, 0], M[3, 1] * 0.5, M[3, 2] * 0.5])
    b, _ = _moves([3], Effect("stride_scale", {"a": 1.2}))
    assert b[0, 0] == pytest.approx(1.2 * M[3, 0])
    b, _ = _moves([3], Effect("lateral_slip", {"gamma": 0.1}))
    assert b[0, 1] == pytest.approx(M[3, 1] + 0.1 * M[3, 2])
    b, _ = _moves([3], Effect("yaw_bias", {"delta": -2}))
    assert b[0, 2] == pytest.approx(M[3, 2] - 2)


def test_transition_blends_first_cycle_after_a_change():
    a = 0.4
    b, _ = _moves([12, 12, 3, 3, 12], Effect("transition", {"alpha": a}))
    assert b[0].tolist() == pytest.approx(M[12].tolist())
    assert b[1].tolist() == pytest.approx(M[12].tolist())
    assert b[2].tolist() == pytest.approx(((1 - a) * M[3] + a * M[12]).tolist())
    assert b[3].tolist() == pytest.approx(M[3].tolist())
    assert b[4].tolist() == pytest.approx(((1 - a) * M[12] + a * M[3]).tolist())


def test_battery_sag_counts_cycles_since_power_on():
    b, _ = _moves([12, 12, 12], Effect("battery_sag", {"beta": 0.01}), n0=10)
    for i in range(3):
        assert b[i].tolist() == pytest.approx((M[12] * (1 - 0.01 * (10 + i))).tolist())


def test_floor_slope_adds_world_drift():
    p = rollout(M, (45, 30, 90), [12], [Effect("floor_slope", {"s": 2.0, "theta": 90.0})])
    # heading 90: F to +x; drift towards compass 90 = +x as well
    assert p[1].tolist() == pytest.approx([45 + 12.1 + 2.0, 30 + 0.1, 90.0])


def test_effects_compose_in_canonical_order_whatever_the_list_order():
    e1, e2 = Effect("yaw_bias", {"delta": 1.0}), Effect("turn_scale", {"c": 2.0})
    a, _ = _moves([3], e1, e2)
    b, _ = _moves([3], e2, e1)
    assert a.tolist() == b.tolist()
    assert a[0, 2] == pytest.approx(M[3, 2] * 2 + 1)  # scale first, then bias


def test_stepwise_world_matches_whole_run():
    """The emulator advances one gait cycle at a time with prev_gait and n0: same path."""
    effs = [Effect("transition", {"alpha": 0.3}), Effect("battery_sag", {"beta": 0.002}),
            Effect("floor_slope", {"s": 0.5, "theta": 200})]
    ids = [12, 12, 3, 3, 19, 12, 3]
    whole = rollout(M, (45, 30, 90), ids, effs, n0=5)
    pose = np.array([45.0, 30.0, 90.0])
    prev = None
    for i, g in enumerate(ids):
        body, world = step_moves(M, np.array([g]), effs, n0=5 + i, prev_gait=prev)
        pose = integrate(pose, body, world)[-1]
        prev = g
        assert pose.tolist() == pytest.approx(whole[i + 1].tolist(), abs=1e-9)


@pytest.mark.parametrize("text, message", [
    ("wobble:x=1", "unknown effect"),
    ("transition:alpha", "expected name:param=value"),
    ("transition:alpha=abc", "is not a number"),
    ("transition:alpha=2", "outside [0, 1]"),
    ("turn_shift:k=1.5", "must be an integer"),
    ("floor_slope:s=1", "parameters must be"),
])
def test_parse_effect_errors(text, message):
    with pytest.raises(InputError, match=message.replace("[", r"\[")):
        parse_effect(text)


def test_parse_effect_ok():
    e = parse_effect("floor_slope:s=1.5,theta=30")
    assert e.params == {"s": 1.5, "theta": 30.0}
    assert str(e) == "floor_slope:s=1.5,theta=30"
