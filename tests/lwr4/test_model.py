"""The LWR4+ MJCF against the published facts, and MuJoCo against Pinocchio on that one file."""

from __future__ import annotations

import itertools
import math
import xml.etree.ElementTree as ET

import mujoco  # type: ignore[import-untyped]
import numpy as np
import pinocchio as pin  # type: ignore[import-untyped]
import pytest
from numpy.typing import NDArray

from stdlib.lwr4plus.dynamics import (
    MJCF_PATH,
    Lwr4Dynamics,
    circle_point,
    circle_reference,
    circle_velocity,
    cw_then_ccw_phase,
    impedance_torque,
)
from stdlib.lwr4plus.mujoco_arm import MujocoLwr4

Vector = NDArray[np.float64]

# Facts table (reference/lwr4plus-facts.md): standard DH, a_i = 0.
DH_D = (0.3105, 0.0, 0.40, 0.0, 0.39, 0.0, 0.078)
DH_ALPHA = (
    math.pi / 2,
    -math.pi / 2,
    -math.pi / 2,
    math.pi / 2,
    math.pi / 2,
    -math.pi / 2,
    0.0,
)
LIMITS_DEG = (170.0, 120.0, 170.0, 120.0, 170.0, 120.0, 170.0)
TORQUES = (176.0, 176.0, 100.0, 100.0, 100.0, 38.0, 38.0)
HOLD_POSE = np.array([0.3, -0.6, 0.2, 1.4, -0.3, -1.1, 0.4])


@pytest.fixture(scope="module")
def dyn() -> Lwr4Dynamics:
    return Lwr4Dynamics()


@pytest.fixture(scope="module")
def arm() -> MujocoLwr4:
    return MujocoLwr4()


def random_configurations(n: int, seed: int) -> Vector:
    limits = np.deg2rad(LIMITS_DEG)
    return np.random.default_rng(seed).uniform(-limits, limits, size=(n, 7))


def dh_flange(q: Vector) -> NDArray[np.float64]:
    """Homogeneous transform base -> flange of the standard DH chain of the facts table."""
    t = np.eye(4)
    for theta, d, alpha in zip(q, DH_D, DH_ALPHA, strict=True):
        ct, st, ca, sa = (
            math.cos(theta),
            math.sin(theta),
            math.cos(alpha),
            math.sin(alpha),
        )
        t = t @ np.array(
            [
                [ct, -st * ca, st * sa, 0.0],
                [st, ct * ca, -ct * sa, 0.0],
                [0.0, sa, ca, d],
                [0.0, 0.0, 0.0, 1.0],
            ]
        )
    return t


def test_gravity_matches_mujoco_bias_at_rest(
    dyn: Lwr4Dynamics, arm: MujocoLwr4
) -> None:
    worst = 0.0
    for q in random_configurations(250, seed=1):
        arm.reset(q)
        worst = max(worst, float(np.abs(dyn.gravity(q) - arm.data.qfrc_bias).max()))
    assert worst < 1e-9
    # Not vacuous: gravity is large away from the upright pose.
    assert np.abs(dyn.gravity(HOLD_POSE)).max() > 10.0


def test_bias_and_mass_matrix_match_with_velocity(
    dyn: Lwr4Dynamics, arm: MujocoLwr4
) -> None:
    rng = np.random.default_rng(2)
    mass = np.zeros((7, 7))
    for q in random_configurations(50, seed=3):
        dq = rng.normal(size=7)
        arm.reset(q, dq)
        bias = pin.rnea(dyn.model, dyn.data, q, dq, np.zeros(7))
        assert np.allclose(bias, arm.data.qfrc_bias, rtol=0.0, atol=1e-9)
        mujoco.mj_fullM(arm.model, arm.data, mass)
        crba = np.triu(pin.crba(dyn.model, dyn.data, q))
        assert np.allclose(crba + np.triu(crba, 1).T, mass, rtol=0.0, atol=1e-12)


def test_forward_kinematics_is_the_dh_chain(dyn: Lwr4Dynamics, arm: MujocoLwr4) -> None:
    assert np.allclose(dyn.ee_position(np.zeros(7)), [0.0, 0.0, sum(DH_D)], atol=1e-12)
    for q in random_configurations(100, seed=4):
        t = dh_flange(q)
        assert np.abs(dyn.ee_position(q) - t[:3, 3]).max() < 1e-9
        placement = dyn.data.oMf[dyn.ee_frame_id]
        assert np.abs(placement.rotation - t[:3, :3]).max() < 1e-9
        arm.reset(q)
        assert np.abs(arm.ee_position() - t[:3, 3]).max() < 1e-9


def test_joint_and_torque_limits_in_mujoco(arm: MujocoLwr4, dyn: Lwr4Dynamics) -> None:
    m = arm.model
    limits = np.deg2rad(LIMITS_DEG)
    assert m.nq == m.nv == m.nu == 7
    assert np.all(m.jnt_type == mujoco.mjtJoint.mjJNT_HINGE)
    assert np.all(m.jnt_limited == 1)
    assert np.allclose(m.jnt_range, np.column_stack([-limits, limits]), atol=1e-12)
    torque_range = np.column_stack([-np.array(TORQUES), TORQUES])
    assert np.all(m.actuator_ctrllimited == 1)
    assert np.allclose(m.actuator_ctrlrange, torque_range)
    assert np.all(m.jnt_actfrclimited == 1)
    assert np.allclose(m.jnt_actfrcrange, torque_range)
    assert np.all(m.actuator_gaintype == mujoco.mjtGain.mjGAIN_FIXED)
    assert np.allclose(m.actuator_gear[:, 0], 1.0)
    assert m.opt.timestep == 0.001
    assert m.opt.integrator == mujoco.mjtIntegrator.mjINT_IMPLICITFAST
    # Pinocchio reads the same limits from the same file.
    assert np.allclose(dyn.model.upperPositionLimit, limits)
    assert np.allclose(dyn.model.effortLimit, TORQUES)


# kuka-isir CAD column of the facts table: base, links 1..7.
CAD_MASSES = (1.210, 2.303, 2.303, 2.303, 2.303, 1.601, 1.493, 0.109)
CAD_COMS = (
    (-0.0006, 0.0, 0.048),
    (0.0, 0.0233, 0.1181),
    (0.0, -0.0327, 0.0737),
    (0.0, -0.0233, 0.1182),
    (0.0, 0.0327, 0.0737),
    (0.0, 0.0208, 0.0862),
    (0.0, -0.0045, -0.0030),
    (0.0, 0.0, -0.0158),
)


def test_masses_and_centres_of_mass_are_the_cad_column(arm: MujocoLwr4) -> None:
    m = arm.model
    assert m.nbody == 9  # world + base + 7 links
    assert np.allclose(m.body_mass[1:], CAD_MASSES, rtol=0.0, atol=1e-12)
    assert np.allclose(m.body_ipos[1:], CAD_COMS, rtol=0.0, atol=1e-12)
    for inertia in m.body_inertia[1:]:  # principal moments: physically consistent
        a, b, c = inertia
        assert min(a, b, c) > 0.0 and a + b >= c and b + c >= a and a + c >= b


def test_apply_torque_clips_to_limits(arm: MujocoLwr4) -> None:
    arm.reset(np.zeros(7))
    applied = arm.apply_torque(np.full(7, 500.0))
    assert np.allclose(applied, TORQUES)
    assert np.allclose(arm.data.ctrl, TORQUES)
    arm.apply_torque(np.zeros(7))


def test_jacobian_matches_finite_differences(
    dyn: Lwr4Dynamics, arm: MujocoLwr4
) -> None:
    h = 1e-6
    jacp = np.zeros((3, 7))
    jacr = np.zeros((3, 7))
    for q in random_configurations(20, seed=5):
        jac = dyn.jacobian(q)
        assert jac.shape == (6, 7)
        fd = np.column_stack(
            [
                (dyn.ee_position(q + h * e) - dyn.ee_position(q - h * e)) / (2 * h)
                for e in np.eye(7)
            ]
        )
        assert np.abs(jac[:3] - fd).max() < 1e-8
        arm.reset(q)
        site = mujoco.mj_name2id(arm.model, mujoco.mjtObj.mjOBJ_SITE, "ee")
        mujoco.mj_jacSite(arm.model, arm.data, jacp, jacr, site)
        assert np.abs(jac - np.vstack([jacp, jacr])).max() < 1e-12


def test_gravity_jacobian_position_is_fresh(dyn: Lwr4Dynamics) -> None:
    qa, qb = random_configurations(2, seed=7)
    expected = dyn.ee_position(qb), dyn.jacobian(qb), dyn.gravity(qb)
    dyn.ee_position(qa)  # leave the scratch data at another configuration
    g, jac, p = dyn.gravity_jacobian_position(qb)
    assert np.array_equal(p, expected[0])
    assert np.array_equal(jac, expected[1])
    assert np.array_equal(g, expected[2])


def test_state_velocity_from_mujoco_matches_pinocchio(
    dyn: Lwr4Dynamics, arm: MujocoLwr4
) -> None:
    rng = np.random.default_rng(6)
    arm.reset(HOLD_POSE, rng.normal(size=7))
    arm.apply_torque(rng.normal(size=7))
    arm.step(3)
    s = arm.state()
    assert s.time == pytest.approx(0.003)
    assert np.abs(s.ee_pos - dyn.ee_position(s.q)).max() < 1e-12
    assert np.abs(s.ee_vel - dyn.ee_velocity(s.q, s.dq)).max() < 1e-12
    assert np.linalg.norm(s.ee_vel) > 0.01
    arm.apply_torque(np.zeros(7))


def test_gravity_compensated_hold_is_still(dyn: Lwr4Dynamics, arm: MujocoLwr4) -> None:
    arm.reset(HOLD_POSE)
    for _ in range(2000):
        s = arm.state()
        arm.apply_torque(dyn.gravity(s.q))
        arm.step()
    s = arm.state()
    assert s.time == pytest.approx(2.0)
    assert np.abs(s.q - HOLD_POSE).max() < 1e-3
    assert np.abs(s.dq).max() < 1e-3


def test_perturbed_hold_only_loses_energy(dyn: Lwr4Dynamics, arm: MujocoLwr4) -> None:
    # Gravity compensated, the joint damping is the only force left: the kinetic energy
    # must fall at every 1 ms step (an unstable integration would pump energy in).
    arm.reset(HOLD_POSE, np.full(7, 0.2))
    mass = np.zeros((7, 7))
    energies = []
    for _ in range(2000):
        s = arm.state()
        arm.apply_torque(dyn.gravity(s.q))
        arm.step()
        mujoco.mj_fullM(arm.model, arm.data, mass)
        energies.append(0.5 * arm.data.qvel @ mass @ arm.data.qvel)
    assert np.all(np.diff(energies) < 0.0)
    assert energies[-1] < 0.5 * energies[0]


def test_without_compensation_the_arm_falls(arm: MujocoLwr4) -> None:
    arm.reset(HOLD_POSE)
    arm.apply_torque(np.zeros(7))
    arm.step(500)
    assert np.abs(arm.state().q - HOLD_POSE).max() > 0.05


@pytest.mark.parametrize("damp_velocity_error", [True, False])
def test_impedance_converges_to_nearby_target(
    dyn: Lwr4Dynamics, arm: MujocoLwr4, damp_velocity_error: bool
) -> None:
    arm.reset(HOLD_POSE)
    target = arm.ee_position() + np.array([0.03, -0.02, 0.02])
    for _ in range(2000):
        s = arm.state()
        tau = impedance_torque(
            s.q, s.dq, target, np.zeros(3), 3000.0, 100.0, damp_velocity_error, dyn
        )
        arm.apply_torque(tau)
        arm.step()
    s = arm.state()
    assert np.linalg.norm(s.ee_pos - target) < 1e-3
    assert np.linalg.norm(s.ee_vel) < 1e-2


def test_impedance_torque_is_gravity_at_the_target(dyn: Lwr4Dynamics) -> None:
    p = dyn.ee_position(HOLD_POSE)
    tau = impedance_torque(
        HOLD_POSE, np.zeros(7), p, np.zeros(3), 2000.0, 100.0, True, dyn
    )
    assert np.allclose(tau, dyn.gravity(HOLD_POSE), atol=1e-12)
    # A matrix gain pushing along +x only gives J_v^T [k dx, 0, 0].
    K = np.diag([1000.0, 0.0, 0.0])
    target = p + np.array([0.01, 0.02, 0.03])
    tau_k = impedance_torque(
        HOLD_POSE, np.zeros(7), target, np.zeros(3), K, 0.0, True, dyn
    )
    jv = dyn.jacobian(HOLD_POSE)[:3]
    assert np.allclose(
        tau_k - dyn.gravity(HOLD_POSE), jv.T @ [10.0, 0.0, 0.0], atol=1e-9
    )


def test_circle_helpers() -> None:
    centre = np.array([0.5, 0.0, 0.4])
    for phase in np.linspace(-7.0, 7.0, 29):
        p = circle_point(centre, 0.05, phase, "xy")
        assert abs(np.linalg.norm(p - centre) - 0.05) < 1e-15
        assert p[2] == centre[2]
        h = 1e-6
        fd = (
            circle_point(centre, 0.05, phase + h)
            - circle_point(centre, 0.05, phase - h)
        ) / (2 * h)
        assert np.allclose(circle_velocity(0.05, phase, 1.0), fd, atol=1e-9)
    # A negative phase rate runs clockwise seen from above: (p - c) x v points down.
    p = circle_point(centre, 0.05, 0.3)
    assert np.cross(p - centre, circle_velocity(0.05, 0.3, -1.0))[2] < 0.0
    assert np.allclose(circle_point(centre, 0.05, 0.0, "yz"), centre + np.array([0.0, 0.05, 0.0]))


def test_cw_then_ccw_phase_profile() -> None:
    period = 2.5
    times = np.arange(0.0, 2 * period + 0.5, 0.001)
    phases, rates = np.array([cw_then_ccw_phase(t, period) for t in times]).T
    assert phases[0] == 0.0 and rates[0] == 0.0
    assert phases[times.searchsorted(period)] == pytest.approx(-2 * math.pi)
    assert phases[-1] == pytest.approx(0.0, abs=1e-12) and rates[-1] == 0.0
    assert np.all(rates[times < period] <= 0.0) and np.all(rates[times > period] >= 0.0)
    assert np.allclose(np.gradient(phases, times), rates, atol=2e-3)
    _, v = zip(
        *(circle_reference(t, np.zeros(3), 0.05, period) for t in times), strict=True
    )
    assert max(np.linalg.norm(v, axis=1)) == pytest.approx(0.236, abs=1e-3)


def test_model_file_is_self_contained_and_documents_its_inertials() -> None:
    parser = ET.XMLParser(target=ET.TreeBuilder(insert_comments=True))
    root = ET.fromstring(MJCF_PATH.read_text(), parser=parser)
    elements = list(root.iter())
    assert not [e for e in elements if e.tag in ("include", "mesh")]
    assert not [e for e in elements if "gravcomp" in e.attrib]
    inertials = 0
    for parent in elements:
        children = list(parent)
        for before, child in itertools.pairwise(children):
            if child.tag == "inertial":
                inertials += 1
                tag: object = before.tag  # comments carry the ET.Comment factory as tag
                assert tag is ET.Comment, f"no source comment before {child.attrib}"
                assert "estimated:" in (before.text or "")
    assert inertials == 8
