"""The rod of ``softflow.rod.Simulator(robot, gravity="none")`` in PyElastica (benchmark only).

``simulate`` runs one episode of the same rod and input in PyElastica, an explicit,
discrete, extensible and shearable Cosserat-rod code, so that a benchmark can report
our speed-up and the tip-trajectory difference (and that of every segment's end disk,
for a rod of several segments such as ``TWO_SEGMENT_ROD``). It needs the separate venv of
benchmarks/README.md (PyElastica pulls numba). ``python benchmarks/pyelastica_rod.py``
runs the validation against our simulator.

How the model is matched:

* Rod: straight along +x, directors d1 = +y, d2 = +z, d3 = +x; circular section of
  ``robot.diameter``, ``robot.density``, E = ``robot.youngs_modulus`` and PyElastica's
  default shear modulus G = E/3 (Poisson 0.5), passed explicitly. Stretch and shear
  then deflect the tip (D/L)^2 ~ 1e-4 of bending: nearly inextensible and
  unshearable, as ours. No gravity. Rotary inertia is PyElastica's (ours has none;
  its effect on the modes is (D/L)^2 small).
* Clamp: PyElastica clamps the first element, whose centre then acts as the clamp,
  and a uniform bend turns the tip a rotation kappa l / 2 short of the arc. The rod
  therefore starts half an element behind the origin and is half an element longer:
  clamp at the origin, tip at x = L, and the static tip error drops from O(1/n) to
  O(1/n^2) (u = (2, 1), 25 elements: 7.5 mm -> 0.07 mm; 2 s responses: 28 -> 0.4 mm).
* Torsion: ours is torsion-free (kappa_3 = 0). The twist stiffness GJ is multiplied
  by ``TORSION_FACTOR``; with PyElastica's own GJ the 3-D input twists the rod, which
  turns the cables' bending plane: 42 mm off.
* Cables: a differential tension u applies the body-frame moment m = r (-u_2, u_1)
  (components on d1, d2; r = cable_distance/2) along the whole length, like our
  cable map. PyElastica's bending couple is B (kappa - kappa_0), so m enters as the
  rest curvature kappa_0 = B^-1 m. This yields the follower couple m at the tip and
  also the distributed twisting couple m x kappa that an internal body-fixed moment
  exerts once the rod bends out of the cables' plane; a tip couple alone misses it
  (19 mm off for the 3-D input).
* Segments (``robot.cable_anchors``): a cable group anchored at s_g loads [0, s_g] only,
  as our cable map, so m is piecewise constant: at arc length s the sum of
  r (-u_z, u_y) over the groups whose disk lies beyond s. PyElastica's curvature lives on
  its n - 1 interior nodes, node k standing for [k l, (k + 1) l] from the clamp (l the
  element length); each gets the rest curvature of m averaged over that arc, so the
  rest curvature integrates exactly across a disk (with the half-element shift no
  element count puts TWO_SEGMENT_ROD's middle disk on such a boundary: at 25 elements it
  lies a quarter into node 12's arc). Clamp, torsion, damping and time step as for one
  segment; one segment gets the same numbers as before. A disk is read on the
  centreline between the two nodes around it, linearly (the tip is the last node).
  Statics of three S-shaped inputs (u1, u3 of opposite signs, settled): tip 0.015-0.053
  mm from the piecewise arcs, middle disk 0.011-0.029 mm; at 50 elements the worst
  (u = (-3, 1, 2, 1)) drops to 0.013 and 0.018 mm, O(1/n^2) as for one segment. On the
  2 s response of bench_two_segment.py, 50 elements with 2.5 us move the tip by 0.22 mm
  and the middle disk by 0.15 mm.
* Damping: ours is Kelvin-Voigt, couple E I kappa + eta I kappa_dot, so the modal
  ratios are zeta_n = eta omega_n / (2 E): 0.112, 0.70, 1.97 for SIM_ROBOT (Euler-
  Bernoulli modes 1.43, 8.95, 25.1 Hz). PyElastica has no such damper; its
  AnalyticalLinearDamper is mass-proportional (zeta_n = gamma / (2 omega_n)), so matched
  on mode 1 (gamma = 2 zeta_1 omega_1 = eta omega_1^2 / E = 2.01 1/s) it leaves mode 2
  at zeta = 0.018 and the tip 19 mm off on the step. The dashpot cannot be added as an
  explicit couple either: acting on an element's rotary inertia it relaxes in
  rho l^2 / (4 eta) ~ 1e-8 s. So the same eta is put in a standard linear solid, the
  dashpot in series with a spring ``KV_STIFFNESS_RATIO`` E, both parallel to E:
  modulus E + i omega eta / (1 + i omega tau), tau = eta / (KV_STIFFNESS_RATIO E)
  = 0.83 ms, which is Kelvin-Voigt for omega tau << 1. Mode 1 (omega_1 tau = 0.0075)
  keeps zeta_1 = 0.112 (-0.2 %) and its frequency (+0.08 %); modes 2 and 3 get
  zeta 0.66 and 1.28 instead of 0.70 and 1.97 (both strongly damped either way).
  The dashpot strain kappa_v is advanced exactly each step (kappa held) and the law
  enters PyElastica through its couple B (kappa - kappa_0): B is scaled by 1 + ratio
  and kappa_0 = ratio / (1 + ratio) kappa_v + B^-1 m. Its stiff branch sets the
  stable time step: 5 us at 25 elements (6.25 us diverges) where the plain rod runs
  at 8 us.
"""

from __future__ import annotations

import math
import time

import elastica as ea
import numpy as np

KV_STIFFNESS_RATIO = 30.0  # spring in series with the dashpot, in units of E
TORSION_FACTOR = 100.0  # GJ multiplier standing in for our torsion-free rod


class _System(ea.BaseSystemCollection, ea.Constraints):
    """A PyElastica simulation with boundary conditions."""


class _BendingLaw:
    """Bending couple E I kappa + (viscous branch) - m of our rod, written into the rod's
    bend matrix and rest curvature; ``after_step`` advances the dashpot strain exactly
    over one time step (kappa held), ``cable_moment`` sets m for the next sample."""

    def __init__(self, rod, robot, time_step: float, element: float):
        rod.bend_matrix[:2, :2] *= 1 + KV_STIFFNESS_RATIO
        rod.bend_matrix[2, 2] *= TORSION_FACTOR
        self.rod = rod
        self.stiffness = np.stack([rod.bend_matrix[0, 0], rod.bend_matrix[1, 1]])  # (2, n-1)
        relaxation = (
            time_step * KV_STIFFNESS_RATIO * robot.youngs_modulus / robot.damping if robot.damping else math.inf
        )
        self.decay = math.exp(-relaxation)  # no damping: the branch follows kappa and adds nothing
        self.viscous_kappa = np.zeros_like(self.stiffness)
        self.moment = np.zeros((2, 1))
        # Share of node k's Voronoi domain [k l, (k+1) l] (arc length from the clamp) that a
        # cable group anchored at s_g loads: 1 before its disk, 0 beyond, a fraction across it.
        starts = element * np.arange(self.stiffness.shape[1])  # (n-1,)
        anchors = np.array(sorted(set(robot.anchors)))  # (G,), base outwards
        self.loaded = np.clip((anchors[None] - starts[:, None]) / element, 0.0, 1.0)  # (n-1, G)
        self.cable_radius = robot.cable_radius

    def _set_rest_kappa(self):
        share = KV_STIFFNESS_RATIO / (1 + KV_STIFFNESS_RATIO)
        self.rod.rest_kappa[:2] = share * self.viscous_kappa + self.moment / self.stiffness

    def cable_moment(self, u):
        """u (m,): one pair (u_y, u_z) per cable group, base outwards."""
        pairs = self.loaded @ u.reshape(-1, 2)  # (n-1, 2): the groups whose disk lies beyond each node
        self.moment = self.cable_radius * np.stack([-pairs[:, 1], pairs[:, 0]])  # (2, n-1) on d1, d2
        self._set_rest_kappa()

    def after_step(self):
        self.viscous_kappa += (1 - self.decay) * (self.rod.kappa[:2] - self.viscous_kappa)
        self._set_rest_kappa()


def _disk_nodes(robot, element: float) -> tuple[np.ndarray, np.ndarray]:
    """The node before each segment's end disk and the disk's fraction of the way to the next
    (node k lies at arc length (k - 1/2) l from the clamp, so the tip is node n, fraction 0)."""
    place = np.array(robot.segment_ends) / element + 0.5
    nodes = np.minimum(np.floor(place + 1e-9).astype(int), round(robot.length / element + 0.5))
    return nodes, place - nodes


def simulate(
    robot, u, dt: float = 0.01, duration: float | None = None, n_elements: int = 25, time_step: float = 5e-6
) -> dict:
    """Tip and disk trajectories of one episode in PyElastica, from rest.

    u: (T, m) differential cable tensions (N), one pair per cable group as in our
    simulator (m = robot.n_inputs), each held for ``dt`` s (the last one beyond T dt when
    ``duration`` is longer). ``time_step`` must divide ``dt``; the default (25 elements,
    5 us) is converged and within the explicit stability limit, which the stiff viscous
    branch and torsion set (see benchmarks/README.md).
    Returns times (S+1,), tip (S+1, 3) and disks (S+1, segments, 3) (each segment's end,
    the tip last) positions in m at every sample, and wall_seconds, the time spent
    integrating after the first step (setup and numba's compilation, which a fresh venv
    pays on that step, excluded).
    """
    u = np.asarray(u, dtype=float)
    m = robot.n_inputs
    if u.ndim != 2 or u.shape[1] != m or len(u) == 0 or not np.isfinite(u).all():
        raise ValueError(f"u must be a finite (T, {m}) array; got shape {u.shape}")
    samples = len(u) if duration is None else round(duration / dt)
    if samples < 1:
        raise ValueError(f"duration must cover at least one sample of {dt} s; got {duration!r}")
    steps = round(dt / time_step)
    if steps < 1 or not math.isclose(steps * time_step, dt, rel_tol=1e-9):
        raise ValueError(f"time_step must divide dt; got {time_step!r} and {dt!r}")
    h = dt / steps

    element = robot.length / (n_elements - 0.5)  # half an element behind the clamp
    rod = ea.CosseratRod.straight_rod(
        n_elements,
        np.array([-element / 2, 0.0, 0.0]),
        np.array([1.0, 0.0, 0.0]),
        np.array([0.0, 1.0, 0.0]),
        n_elements * element,
        robot.diameter / 2,
        robot.density,
        youngs_modulus=robot.youngs_modulus,
        shear_modulus=robot.youngs_modulus / 3,
    )
    law = _BendingLaw(rod, robot, h, element)
    system = _System()
    system.append(rod)
    system.constrain(rod).using(ea.OneEndFixedBC, constrained_position_idx=(0,), constrained_director_idx=(0,))
    system.finalize()

    nodes, fraction = _disk_nodes(robot, element)
    after = np.minimum(nodes + 1, n_elements)

    def disks():
        x = rod.position_collection.T  # (n+1, 3)
        return x[nodes] + fraction[:, None] * (x[after] - x[nodes])

    stepper, t = ea.PositionVerlet(), 0.0
    disk = np.empty((samples + 1, len(nodes), 3))
    disk[0] = disks()
    start = None
    for k in range(samples):
        law.cable_moment(u[min(k, len(u) - 1)])
        for _ in range(steps):
            t = stepper.step(system, t, h)
            law.after_step()
            start = start or time.perf_counter()  # after the first step, which compiles numba's kernels
        disk[k + 1] = disks()
    wall = time.perf_counter() - start
    if not np.isfinite(disk).all():
        raise RuntimeError("PyElastica diverged: reduce time_step")
    return dict(times=dt * np.arange(samples + 1), tip=disk[:, -1].copy(), disks=disk, wall_seconds=wall)


def main():
    """Validate against our simulator: statics (signs), a smooth 3-D and a step
    response over 2 s, PyElastica's convergence, and timings."""
    import dataclasses

    from softflow.rod.dynamics import Simulator
    from softflow.rod.robots import SIM_ROBOT as robot

    ours = Simulator(robot, gravity="none")
    L = robot.length

    # Statics: a heavier damping (zeta_1 ~ 0.7) settles in 2 s; the equilibrium does not depend on it.
    settled = dataclasses.replace(robot, damping=6 * robot.damping)
    for u in ([2.0, 1.0], [-1.5, -0.5]):
        tip = simulate(settled, [u], duration=2.0)["tip"][-1]
        exact = ours.static_tip(np.array([u]))[0]
        print(
            f"static u={u}: PyElastica {np.round(tip * 1e3, 2)} mm, ours {np.round(exact * 1e3, 2)} mm, "
            f"difference {np.linalg.norm(tip - exact) * 1e3:.3f} mm"
        )

    t = np.arange(200) * 0.01
    inputs = {
        "smooth": np.stack([2 * np.sin(2 * np.pi * 0.8 * t), 1.5 * (1 - np.cos(2 * np.pi * 0.5 * t))], -1),
        "step (2, 1)": np.tile([2.0, 1.0], (200, 1)),
    }
    for name, u in inputs.items():
        result = simulate(robot, u)
        fine = simulate(robot, u, n_elements=50, time_step=2.5e-6)
        start = time.perf_counter()
        X = ours.rollout(u[None])[0, :, :3]
        single = time.perf_counter() - start
        start = time.perf_counter()
        ours.rollout(np.repeat(u[None], 256, 0))
        batched = (time.perf_counter() - start) / 256
        d = np.linalg.norm(result["tip"] - X, axis=1) * 1e3
        c = np.linalg.norm(result["tip"] - fine["tip"], axis=1) * 1e3
        seconds = len(u) * 0.01
        print(
            f"{name}: max {d.max():.2f} mm ({d.max() / L / 10:.2f} % of L), RMS {np.sqrt(np.mean(d**2)):.2f} mm "
            f"({np.sqrt(np.mean(d**2)) / L / 10:.2f} % of L); "
            f"PyElastica 50 elements/2.5 us vs 25/5 us: max {c.max():.2f} mm"
        )
        print(
            f"  wall per simulated s: PyElastica {result['wall_seconds'] / seconds:.2f} s "
            f"(50 elements {fine['wall_seconds'] / seconds:.2f} s), ours {single / seconds:.3f} s single, "
            f"{batched / seconds:.4f} s per episode batched x256 -> speed-up {result['wall_seconds'] / single:.0f}x "
            f"/ {result['wall_seconds'] / batched:.0f}x"
        )


if __name__ == "__main__":
    main()
