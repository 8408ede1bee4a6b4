"""Identify the robot's unknown parameters from where its moves stopped.

The data are chains: stops seen by a camera (a pose and its uncertainty) linked by the moves
commanded between them. The unknowns are the chosen robot parameters (the assembly offsets
xi2 and xi3, and the friction and cantilever where the data hold them) and the true pose of
each chain's first stop; every later stop is where the slip core says the moves from there
end. The fit is a weighted least squares (Levenberg-Marquardt): residuals are the cameras'
errors in their own standard deviations, so the 95 % intervals follow from the Jacobian.

The model assumes a move repeats exactly what the core predicts (no process noise). A real
robot's unmodelled variation shows as residuals larger than the cameras' noise: the reduced
chi-square then exceeds 1 and the intervals are widened by it.

Moves are rotation- and translation-invariant, so each is simulated once from the origin and
its displacement composed onto the start pose: the poses' derivatives cost no simulation.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from omni_micro_control.chains import Chain, RecordedMove, Stop, wheels_after
from omni_micro_control.errors import IdentificationError
from omni_micro_sim.errors import SimulationError
from omni_micro_sim.parameters import RobotParameters
from omni_micro_sim.state import RobotState

# A 95 % interval is this many standard deviations either side.
Z_95 = 1.959963984540054


@dataclass(frozen=True)
class FreeParameter:
    """A robot parameter the fit may estimate, under its dynamics_node ROS parameter name."""

    ros_name: str
    label: str
    unit: str
    display_scale: float        # SI value times this = the value in ``unit``
    fd_step: float              # finite-difference step, SI
    prior_sigma: float          # a weak prior's spread, SI: it only keeps the fit well posed
    max_half_width: float       # a 95 % half-width beyond this means "not identifiable", SI
    get: Callable[[RobotParameters], float]
    put: Callable[[RobotParameters, float], RobotParameters]


def _offset(index: int) -> FreeParameter:
    def get(robot: RobotParameters) -> float:
        return robot.wheel_offsets_rad[index]

    def put(robot: RobotParameters, value: float) -> RobotParameters:
        offsets = list(robot.wheel_offsets_rad)
        offsets[index] = value
        return robot.replace(wheel_offsets_rad=tuple(offsets))

    return FreeParameter(f'robot.wheel_offsets_rad[{index}]', f'xi{index + 1}', 'deg',
                         math.degrees(1.0), 1e-6, math.radians(10.0), math.radians(1.0),
                         get, put)


def _field(name: str, label: str, unit: str, scale: float, step: float, prior: float,
           widest: float) -> FreeParameter:
    return FreeParameter(f'robot.{name}', label, unit, scale, step, prior, widest,
                         lambda robot: float(getattr(robot, name)),
                         lambda robot, value: robot.replace(**{name: value}))


def _steering_field(name: str, label: str, unit: str, scale: float, step: float,
                    prior: float, widest: float) -> FreeParameter:
    def put(robot: RobotParameters, value: float) -> RobotParameters:
        return robot.replace(steering=robot.steering.replace(**{name: value}))

    return FreeParameter(f'robot.steering.{name}', label, unit, scale, step, prior, widest,
                         lambda robot: float(getattr(robot.steering, name)), put)


# Wheel 1's offset is the reference the steering angle is measured from: always 0.
PARAMETERS = {
    'xi2': _offset(1),
    'xi3': _offset(2),
    'mu_longitudinal': _field('mu_longitudinal', 'mu_L', '', 1.0, 1e-6, 0.5, 0.05),
    'mu_transverse': _field('mu_transverse', 'mu_T', '', 1.0, 1e-6, 0.5, 0.05),
    'cantilever_offset_m': _field('cantilever_offset_m', 'd1', 'mm', 1e3, 1e-9, 2e-3, 0.3e-3),
    # Only with a steering motion (docs/model.md, "Steering dynamics").
    'backlash': _steering_field('backlash_rad', 'backlash', 'deg', math.degrees(1.0), 1e-6,
                                math.radians(2.0), math.radians(0.2)),
    'contact_radius': _steering_field('contact_radius_m', 'a', 'um', 1e6, 1e-8, 100e-6,
                                      20e-6),
}
STEERING_FITS = ('backlash', 'contact_radius')
OFFSETS = ('xi2', 'xi3')


@dataclass(frozen=True)
class Prior:
    """What is known of the free parameters before the data: a mean and a covariance (SI)."""

    mean: np.ndarray
    covariance: np.ndarray


def compose(pose: np.ndarray, displacement: np.ndarray) -> np.ndarray:
    """The pose reached by ``displacement`` (in the frame of ``pose``) from ``pose``."""
    cos_phi, sin_phi = math.cos(pose[2]), math.sin(pose[2])
    return np.array([pose[0] + cos_phi * displacement[0] - sin_phi * displacement[1],
                     pose[1] + sin_phi * displacement[0] + cos_phi * displacement[1],
                     pose[2] + displacement[2]])


def inverse(displacement: np.ndarray) -> np.ndarray:
    """The displacement that undoes ``displacement``: compose(compose(p, d), inverse(d)) = p."""
    cos_phi, sin_phi = math.cos(displacement[2]), math.sin(displacement[2])
    return np.array([-cos_phi * displacement[0] - sin_phi * displacement[1],
                     sin_phi * displacement[0] - cos_phi * displacement[1],
                     -displacement[2]])


def displacement(robot: RobotParameters, move: RecordedMove) -> np.ndarray:
    """Where ``move`` takes the robot from rest at the origin heading 0: (x, y, phi)."""
    # The slip core (numba) loads with the first prediction, not with the module: the paper's
    # mode of controller_node imports this module and never predicts.
    from omni_micro_sim.open_loop import run_to_rest
    from omni_micro_sim.steering import plan_steering

    motion = None
    if move.gear_path and not robot.steering.instantaneous:
        wheels = wheels_after(move.gear_path, robot.steering.backlash_rad)
        motion = plan_steering(robot.steering, move.gear_path[-1], wheels, move.steering_rad)
    final, _ = run_to_rest(robot, move.steering_rad, move.profile, RobotState(), motion=motion)
    return np.array([final.x_m, final.y_m, final.phi_rad])


def wrap(angle: np.ndarray | float) -> np.ndarray:
    return np.remainder(np.asarray(angle) + math.pi, 2.0 * math.pi) - math.pi


@dataclass(frozen=True)
class Fit:
    """The fitted parameters and what the data say of them."""

    names: tuple[str, ...]
    robot: RobotParameters
    values: np.ndarray               # SI, in ``names`` order
    covariance: np.ndarray           # SI, widened by the reduced chi-square when above 1
    half_widths_95: np.ndarray       # SI
    residuals: list[np.ndarray]      # per chain, per stop: measured - fitted (m, m, rad)
    normalised_residuals: list[np.ndarray]
    chi_square: float                # of the measurements alone
    cost: float                      # chi-square with the prior's term: what the fit minimised
    degrees_of_freedom: int
    iterations: int

    @property
    def reduced_chi_square(self) -> float:
        return self.chi_square / max(1, self.degrees_of_freedom)

    def unidentifiable(self) -> list[str]:
        """The free parameters whose 95 % interval is too wide to call them identified."""
        return [name for name, width in zip(self.names, self.half_widths_95, strict=True)
                if not width <= PARAMETERS[name].max_half_width]


def best_seen(stops: Sequence[Stop]) -> int:
    """Index of the stop with the smallest position spread (the latest of equals)."""
    spreads = [float(np.sum(stop.sigmas[:2])) for stop in stops]
    return max(range(len(stops)), key=lambda index: (-spreads[index], index))


class _Problem:
    """The residual function over (free parameters, start poses) with cached simulations."""

    def __init__(self, chains: Sequence[Chain], base: RobotParameters,
                 names: Sequence[str], prior: Prior | None) -> None:
        self.chains = [chain for chain in chains if chain.stops]
        self.base = base
        self.specs = [PARAMETERS[name] for name in names]
        self.prior = prior
        if prior is not None:
            information = np.linalg.inv(prior.covariance)
            self.prior_root = np.linalg.cholesky(information).T
        self._cache: dict[tuple[float, ...], list[list[np.ndarray]]] = {}
        # Each chain's unknown pose is that of its best-seen stop (the latest of equals): the
        # poses of the others follow from it through the moves. Anchored on a micro capture,
        # the fit is nearly linear; anchored on a coarse first stop, the precise stops far down
        # the chain would make it a narrow curved valley.
        self.anchors = [best_seen(chain.stops) for chain in self.chains]

    def robot(self, values: np.ndarray) -> RobotParameters:
        robot = self.base
        for spec, value in zip(self.specs, values, strict=True):
            robot = spec.put(robot, float(value))
        return robot

    def displacements(self, values: np.ndarray) -> list[list[np.ndarray]]:
        key = tuple(float(v) for v in values)
        if key not in self._cache:
            robot = self.robot(values)
            if len(self._cache) > 64:
                self._cache.clear()
            self._cache[key] = [[displacement(robot, move) for move in chain.moves]
                                for chain in self.chains]
        return self._cache[key]

    def fitted_stops(self, theta: np.ndarray) -> list[np.ndarray]:
        """Every stop's pose, composed forward and backward from each chain's anchor."""
        count = len(self.specs)
        steps = self.displacements(theta[:count])
        result = []
        for index, (chain_steps, anchor) in enumerate(zip(steps, self.anchors, strict=True)):
            poses: list[np.ndarray] = [np.empty(3)] * (len(chain_steps) + 1)
            poses[anchor] = theta[count + 3 * index: count + 3 * index + 3]
            for later in range(anchor + 1, len(poses)):
                poses[later] = compose(poses[later - 1], chain_steps[later - 1])
            for earlier in range(anchor - 1, -1, -1):
                poses[earlier] = compose(poses[earlier + 1], inverse(chain_steps[earlier]))
            result.append(np.array(poses))
        return result

    def residuals(self, theta: np.ndarray) -> np.ndarray:
        parts = []
        for chain, fitted in zip(self.chains, self.fitted_stops(theta), strict=True):
            for stop, pose in zip(chain.stops, fitted, strict=True):
                error = stop.pose - pose
                error[2] = wrap(error[2])
                parts.append(error / stop.sigmas)
        if self.prior is not None:
            parts.append(self.prior_root @ (theta[:len(self.specs)] - self.prior.mean))
        return np.concatenate(parts)

    def steps(self, theta: np.ndarray) -> np.ndarray:
        pose_steps = []
        for chain, anchor in zip(self.chains, self.anchors, strict=True):
            sigmas = chain.stops[anchor].sigmas
            pose_steps.extend([max(sigmas[0] * 1e-3, 1e-12), max(sigmas[1] * 1e-3, 1e-12),
                               max(sigmas[2] * 1e-3, 1e-12)])
        return np.array([spec.fd_step for spec in self.specs] + pose_steps)

    def jacobian(self, theta: np.ndarray, at: np.ndarray) -> np.ndarray:
        columns = []
        for index, step in enumerate(self.steps(theta)):
            moved = theta.copy()
            moved[index] += step
            columns.append((self.residuals(moved) - at) / step)
        return np.column_stack(columns)


def fit_parameters(chains: Sequence[Chain], base: RobotParameters, names: Sequence[str],
                   prior: Prior | None = None, *, initial: np.ndarray | None = None,
                   max_iterations: int = 30) -> Fit:
    """Least-squares estimate of the ``names`` parameters of ``base`` from ``chains``.

    Without ``prior`` a weak one (each parameter's ``prior_sigma`` around its value in
    ``base``) keeps a fit with little motion well posed; :meth:`Fit.unidentifiable` then
    names what the data did not pin down. ``initial`` (SI, in ``names`` order) starts the
    search elsewhere than the prior's mean, e.g. at the previous estimate.

    Raises
    ------
    IdentificationError
        If a name is unknown, or there is no move to learn from.
    """
    unknown = [name for name in names if name not in PARAMETERS]
    if unknown:
        raise IdentificationError(
            f'cannot fit {unknown}: the fittable parameters are {sorted(PARAMETERS)}')
    if not any(chain.moves for chain in chains):
        raise IdentificationError('no move between two stops: nothing to learn from')
    specs = [PARAMETERS[name] for name in names]
    if prior is None:
        prior = Prior(np.array([spec.get(base) for spec in specs]),
                      np.diag([spec.prior_sigma ** 2 for spec in specs]))
    problem = _Problem(chains, base, names, prior)
    start = prior.mean if initial is None else np.asarray(initial, dtype=np.float64)
    theta = np.concatenate([start] + [chain.stops[anchor].pose for chain, anchor
                                      in zip(problem.chains, problem.anchors, strict=True)])
    residual = problem.residuals(theta)
    cost = float(residual @ residual)
    damping = 1e-3
    iterations = 0
    for iterations in range(1, max_iterations + 1):  # noqa: B007 (the count is reported)
        jacobian = problem.jacobian(theta, residual)
        normal = jacobian.T @ jacobian
        gradient = jacobian.T @ residual
        improved = False
        while damping < 1e12:
            scaled = normal + damping * np.diag(np.diag(normal) + 1e-30)
            step = -np.linalg.solve(scaled, gradient)
            candidate = theta + step
            try:
                trial = problem.residuals(candidate)
            except (ValueError, RuntimeError):
                trial = None   # a step into unphysical parameters: shorter steps
            if trial is not None and np.all(np.isfinite(trial)) and trial @ trial < cost:
                theta, residual = candidate, trial
                previous, cost = cost, float(trial @ trial)
                damping = max(damping / 10.0, 1e-9)
                improved = True
                break
            damping *= 10.0
        if not improved or previous - cost < 1e-10 * max(previous, 1.0):
            break
    jacobian = problem.jacobian(theta, residual)
    covariance_all = np.linalg.pinv(jacobian.T @ jacobian)
    count = len(specs)
    data_points = sum(3 * len(chain.stops) for chain in problem.chains)
    prior_rows = count
    measurement = residual[:residual.size - prior_rows]
    chi_square = float(measurement @ measurement)
    dof = data_points - (count + 3 * len(problem.chains))
    widen = max(1.0, chi_square / dof) if dof > 0 else 1.0
    covariance = covariance_all[:count, :count] * widen
    fitted = problem.fitted_stops(theta)
    residuals = []
    normalised = []
    for chain, poses in zip(problem.chains, fitted, strict=True):
        measured = np.array([stop.pose for stop in chain.stops])
        error = measured - poses
        error[:, 2] = wrap(error[:, 2])
        residuals.append(error)
        normalised.append(error / np.array([stop.sigmas for stop in chain.stops]))
    values = theta[:count].copy()
    return Fit(tuple(names), problem.robot(values), values, covariance,
               Z_95 * np.sqrt(np.clip(np.diag(covariance), 0.0, None)),
               residuals, normalised, chi_square, cost, dof, iterations)


def identify(chains: Sequence[Chain], names: Sequence[str],
             base: RobotParameters) -> tuple[Fit, dict[str, float]]:
    """Fit ``names``: the offsets first, then each other parameter added alone and kept only
    if the data pin it down (fitting all at once lets the poorly determined ones wander and
    drag the rest). Returns the fit of the identifiable ones and, for the others, the 95 %
    half-width they would have had.

    Raises
    ------
    IdentificationError
        If none of ``names`` is identifiable (the message says how far from it each was).
    """
    dropped: dict[str, float] = {}
    kept: list[str] = []
    fit: Fit | None = None
    ordered = [n for n in names if n in OFFSETS] + [n for n in names if n not in OFFSETS]
    first = [n for n in ordered if n in OFFSETS] or ordered[:1]
    for batch in [first] + [[n] for n in ordered if n not in first]:
        trial_names = kept + batch
        initial = None
        if fit is not None:
            initial = np.concatenate([fit.values, [PARAMETERS[n].get(base) for n in batch]])
        try:
            trial = fit_parameters(chains, base, trial_names, initial=initial)
        except SimulationError:
            # So little motion that the fit wandered to parameters under which a move never
            # comes to rest: none of the batch is pinned down.
            dropped.update(dict.fromkeys(batch, math.inf))
            continue
        vague = trial.unidentifiable()
        if any(name in vague for name in kept):
            vague = batch   # the newcomer made the others vague: it is not pinned down either
        for name in batch:
            if name in vague:
                dropped[name] = float(trial.half_widths_95[trial.names.index(name)])
        if not set(batch) <= set(vague):
            kept += [name for name in batch if name not in vague]
            fit = trial if not vague else fit_parameters(chains, base, kept)
    if fit is None:
        raise IdentificationError(vague_text(dropped))
    return fit, dropped


def vague_text(dropped: dict[str, float]) -> str:
    parts = []
    for name, width in dropped.items():
        spec = PARAMETERS[name]
        interval = (f'+-{width * spec.display_scale:.3g} {spec.unit}'.rstrip()
                    if math.isfinite(width) else 'unbounded')
        parts.append(f'{spec.label} (its 95 % interval would be {interval})')
    return ('not identifiable from this bag, too little motion to pin down: '
            + ', '.join(parts))
