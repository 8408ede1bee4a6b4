"""A study file: what to run, what to vary, what to keep; checked whole before anything runs.

A study is a set of runs of one scenario (``closed_loop``: the vision-feedback loop of the graph,
in the in-process twin; ``open_loop``: one section 3.5 move through the slip core). Each run takes
every parameter of :data:`.inputs.PARAMETERS`: the default, or the study's ``fixed`` value, or a
grid value, or a random draw. Points are the grid's full factorial, times the random draws; each
point runs ``seeds_per_point`` times (camera-noise seeds) in each controller mode.

Expansion is a pure function of the file: run k is the same run whatever executes it, so a
study's rows do not depend on the number of workers, the scheduler, or interruptions.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from omni_micro_common.conventions import MAX_SEED
from omni_micro_sim.parameters import STEERING_PRESETS
from omni_micro_studies.errors import StudyError
from omni_micro_studies.inputs import (
    CLOSED_LOOP,
    METRICS,
    MODES,
    PARAMETERS,
    REQUIRED_METRICS,
    SCENARIOS,
    STEERING_MOTION_PARAMETERS,
)


def _sampler(name: str, spec: Mapping[str, Any],
             where: str) -> tuple[Callable[[np.random.Generator], float], str]:
    """A draw from a named distribution, and how to say it."""
    def number(key: str) -> float:
        if key not in spec:
            raise StudyError(f'{where}.{key}: missing (distribution {name!r} needs it)')
        return _finite(f'{where}.{key}', spec[key])

    if name == 'uniform':
        low, high = number('low'), number('high')
        if not low < high:
            raise StudyError(f'{where}: low must be < high, got low={low:g}, high={high:g}')
        return (lambda rng: float(rng.uniform(low, high))), f'uniform({low:g}, {high:g})'
    if name == 'normal':
        mean, sd = number('mean'), number('sd')
        if sd <= 0.0:
            raise StudyError(f'{where}.sd: expected a number > 0, got {spec["sd"]!r}')
        return (lambda rng: float(rng.normal(mean, sd))), f'normal({mean:g}, {sd:g})'
    if name == 'loguniform':
        low, high = number('low'), number('high')
        if not 0.0 < low < high:
            raise StudyError(f'{where}: needs 0 < low < high, got low={low:g}, high={high:g}')
        return ((lambda rng: float(math.exp(rng.uniform(math.log(low), math.log(high))))),
                f'loguniform({low:g}, {high:g})')
    if name == 'choice':
        values = spec.get('values')
        if not isinstance(values, list) or not values:
            raise StudyError(f'{where}.values: expected a non-empty list, got {values!r}')
        options = [_finite(f'{where}.values[{i}]', v) for i, v in enumerate(values)]
        return (lambda rng: options[int(rng.integers(len(options)))]), f'choice({options})'
    raise StudyError(f'{where}.distribution: expected one of uniform, normal, loguniform, '
                     f'choice, got {name!r}')


def _finite(where: str, value: object) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise StudyError(f'{where}: expected a number, got {value!r}')
    number = float(value)
    if not math.isfinite(number):
        raise StudyError(f'{where}: expected a finite number, got {value!r}')
    return number


# The most runs a study may expand to (grid points x draws x seeds x modes).
MAX_RUNS = 10_000_000


def _whole(where: str, value: object, minimum: int) -> int:
    if isinstance(value, bool) or not isinstance(value, int) or value < minimum:
        raise StudyError(f'{where}: expected a whole number >= {minimum}, got {value!r}')
    return value


@dataclass(frozen=True)
class RandomParameter:
    name: str
    description: str
    seed: int
    draw: Callable[[np.random.Generator], float] = field(compare=False, repr=False)

    def value(self, index: int) -> float:
        # Draw ``index`` comes from its own generator: the same whatever else is drawn.
        return self.draw(np.random.default_rng([self.seed, index]))


@dataclass(frozen=True)
class Study:
    name: str
    description: str
    scenario: str
    fixed: dict[str, float]
    grid: dict[str, list[float]]
    draws: int
    random: list[RandomParameter]
    seeds_per_point: int
    seed: int
    modes: tuple[str, ...]
    metrics: tuple[str, ...]
    text: str          # the file as given, kept beside the results
    steering: str = 'ideal'   # a preset of omni_micro_sim.parameters.STEERING_PRESETS

    @property
    def swept(self) -> list[str]:
        return list(self.grid) + [parameter.name for parameter in self.random]

    @property
    def parameters(self) -> list[str]:
        return [name for name, p in PARAMETERS.items() if self.scenario in p.scenarios]

    @property
    def metric_columns(self) -> list[str]:
        return [column for metric in self.metrics for column in METRICS[metric][0]]

    @property
    def points(self) -> int:
        grid = math.prod(len(values) for values in self.grid.values())
        return grid * (self.draws if self.random else 1)

    @property
    def run_count(self) -> int:
        return self.points * self.seeds_per_point * len(self.modes)

    def runs(self) -> list[dict[str, Any]]:
        """Every run's inputs, in run order: the row a run is re-run from."""
        base = {name: float(PARAMETERS[name].default) for name in self.parameters}
        base.update(self.fixed)
        grid_points = list(itertools.product(*self.grid.values())) or [()]
        draws = range(self.draws) if self.random else [None]
        rows: list[dict[str, Any]] = []
        point = 0
        for values in grid_points:
            for draw in draws:
                inputs = dict(base)
                inputs.update(zip(self.grid, values, strict=True))
                if draw is not None:
                    inputs.update({p.name: p.value(draw) for p in self.random})
                for name in self.parameters:
                    if PARAMETERS[name].whole:
                        inputs[name] = float(round(inputs[name]))
                for replicate in range(self.seeds_per_point):
                    # A point's replicates differ in camera noise only; both modes see the same.
                    seed = self.seed + point * self.seeds_per_point + replicate
                    for mode in self.modes:
                        rows.append({'run': len(rows), 'point': point, 'replicate': replicate,
                                     'mode': mode, 'seed': seed, 'steering': self.steering,
                                     **inputs})
                point += 1
        return rows


def _mapping(where: str, value: object) -> dict[str, Any]:
    if not isinstance(value, dict):
        raise StudyError(f'{where}: expected a mapping of keys to values, got {value!r}')
    return value


def _parameter_name(where: str, name: object, scenario: str) -> str:
    if not isinstance(name, str) or name not in PARAMETERS:
        raise StudyError(f'{where}: unknown parameter {name!r}; known: '
                         f'{", ".join(PARAMETERS)}')
    if scenario not in PARAMETERS[name].scenarios:
        raise StudyError(f'{where}: {name} has no effect on a {scenario} study (it is for '
                         f'{", ".join(PARAMETERS[name].scenarios)})')
    return name


def _in_range(where: str, name: str, value: float) -> float:
    parameter = PARAMETERS[name]
    if not parameter.minimum <= value <= parameter.maximum:
        unit = f' {parameter.unit}' if parameter.unit else ''
        raise StudyError(f'{where}: {name} must be in [{parameter.minimum:g}, '
                         f'{parameter.maximum:g}]{unit}, got {value:g}')
    if parameter.whole and value != round(value):
        raise StudyError(f'{where}: {name} must be a whole number, got {value:g}')
    return value


def _grid_values(where: str, name: str, spec: object, room: int) -> list[float]:
    """An axis's values; ``room``: how many it may have before the grid passes the run limit
    (checked before any is made: a billion steps took 250 MB/s until the machine ran out)."""
    if isinstance(spec, list):
        if not spec:
            raise StudyError(f'{where}: expected at least one value, got []')
        values = [_finite(f'{where}[{i}]', v) for i, v in enumerate(spec)]
    elif isinstance(spec, dict) and set(spec) == {'from', 'to', 'steps'}:
        low, high = _finite(f'{where}.from', spec['from']), _finite(f'{where}.to', spec['to'])
        steps = _whole(f'{where}.steps', spec['steps'], 1)
        if steps > room:
            raise StudyError(f'{where}.steps: {steps} steps make the grid more than '
                             f'{MAX_RUNS:,} runs (the limit; this axis has room for {room:,})')
        values = [float(v) for v in np.linspace(low, high, steps)]
    else:
        raise StudyError(f'{where}: expected a list of values or {{from: A, to: B, steps: N}}, '
                         f'got {spec!r}')
    for i, value in enumerate(values):
        _in_range(f'{where}[{i}]', name, value)
    if len(set(values)) != len(values):
        raise StudyError(f'{where}: values repeat, got {values}')
    return values


TOP_KEYS = ('name', 'description', 'scenario', 'fixed', 'grid', 'random', 'seeds_per_point',
            'seed', 'modes', 'metrics', 'steering')


def parse_study(text: str, source: str = 'study') -> Study:
    """Parse and check a study file's text.

    Raises
    ------
    StudyError
        Naming the key and the value at fault.
    """
    try:
        data = yaml.safe_load(text)
    except yaml.YAMLError as error:
        raise StudyError(f'{source}: not valid YAML: {error}') from None
    data = _mapping(source, data)
    unknown = sorted(set(data) - set(TOP_KEYS), key=str)
    if unknown:
        raise StudyError(f'{unknown[0]}: unknown key; a study has {", ".join(TOP_KEYS)}')
    name = data.get('name', Path(source).stem)
    if not isinstance(name, str) or not name.strip():
        raise StudyError(f'name: expected a non-empty text, got {name!r}')
    description = data.get('description', '')
    if not isinstance(description, str):
        raise StudyError(f'description: expected a text, got {description!r}')
    scenario = data.get('scenario')
    if scenario not in SCENARIOS:
        raise StudyError(f'scenario: expected one of {", ".join(SCENARIOS)}, got {scenario!r}')

    fixed: dict[str, float] = {}
    for key, value in _mapping('fixed', data.get('fixed', {})).items():
        name_ = _parameter_name(f'fixed.{key}', key, scenario)
        fixed[name_] = _in_range(f'fixed.{key}', name_, _finite(f'fixed.{key}', value))

    grid: dict[str, list[float]] = {}
    for key, spec in _mapping('grid', data.get('grid', {})).items():
        name_ = _parameter_name(f'grid.{key}', key, scenario)
        room = MAX_RUNS // math.prod(len(values) for values in grid.values())
        grid[name_] = _grid_values(f'grid.{key}', name_, spec, room)

    random_spec = _mapping('random', data.get('random', {}))
    unknown = sorted(set(random_spec) - {'draws', 'parameters'}, key=str)
    if unknown:
        raise StudyError(f'random.{unknown[0]}: unknown key; random has draws and parameters')
    random: list[RandomParameter] = []
    for key, spec in _mapping('random.parameters', random_spec.get('parameters', {})).items():
        where = f'random.parameters.{key}'
        name_ = _parameter_name(where, key, scenario)
        spec = _mapping(where, spec)
        if 'seed' not in spec:
            raise StudyError(f'{where}.seed: missing (each distribution has its own seed)')
        draw, described = _sampler(str(spec.get('distribution')), spec, where)
        random.append(RandomParameter(name_, described, _whole(f'{where}.seed', spec['seed'],
                                                               0), draw))
    draws = 0
    if random:
        draws = _whole('random.draws', random_spec.get('draws'), 1)
    elif 'draws' in random_spec:
        raise StudyError('random.draws: given, but random.parameters names no parameter')
    if twice := sorted(set(fixed) & (set(grid) | {p.name for p in random})):
        raise StudyError(f'fixed.{twice[0]}: also varied; a parameter is fixed or varied, '
                         'not both')
    if twice := sorted(set(grid) & {p.name for p in random}):
        raise StudyError(f'grid.{twice[0]}: also drawn at random; choose one')

    seeds_per_point = _whole('seeds_per_point', data.get('seeds_per_point', 1), 1)
    seed = _whole('seed', data.get('seed', 0), 0)
    if seed > MAX_SEED:
        raise StudyError(f'seed: expected a whole number in [0, {MAX_SEED}] (each run\'s seed is '
                         f'a ROS integer parameter), got {seed}')
    modes_value = data.get('modes', ['paper'])
    if scenario == 'open_loop':
        if 'modes' in data:
            raise StudyError('modes: an open_loop study has no controller; remove modes')
        modes: tuple[str, ...] = ('open_loop',)
    else:
        if not isinstance(modes_value, list) or not modes_value or any(
                mode not in MODES for mode in modes_value) or len(set(modes_value)) != len(
                modes_value):
            raise StudyError(f'modes: expected a list of distinct controller modes from '
                             f'{", ".join(MODES)}, got {modes_value!r}')
        modes = tuple(modes_value)

    metrics_value = data.get('metrics', list(REQUIRED_METRICS[scenario]))
    if not isinstance(metrics_value, list):
        raise StudyError(f'metrics: expected a list, got {metrics_value!r}')
    for i, metric in enumerate(metrics_value):
        if metric not in METRICS:
            raise StudyError(f'metrics[{i}]: unknown metric {metric!r}; known: '
                             f'{", ".join(METRICS)}')
        if scenario not in METRICS[metric][1]:
            raise StudyError(f'metrics[{i}]: {metric} is not measured in a {scenario} study')
    metrics = tuple(dict.fromkeys([*REQUIRED_METRICS[scenario], *metrics_value]))

    steering = data.get('steering', 'ideal')
    if steering not in STEERING_PRESETS:
        raise StudyError(f'steering: expected one of {", ".join(STEERING_PRESETS)}, got '
                         f'{steering!r}')
    study = Study(name.strip(), description.strip(), scenario, fixed, grid, draws, random,
                  seeds_per_point, seed, modes, metrics, text, steering)
    _check_runs(study)
    if 'steering' in data:
        # Else --steering may still set it: the command checks the study it will run.
        check_steering_parameters(study)
    return study


def check_steering_parameters(study: Study) -> None:
    """With ideal steering the steering motion's parameters play no part: a study varying them
    would record rows that differ only in a number nothing read.

    Raises
    ------
    StudyError
        Naming the first such parameter and where it is set.
    """
    if not STEERING_PRESETS[study.steering].instantaneous:
        return
    for where, names in (('fixed', list(study.fixed)), ('grid', list(study.grid)),
                         ('random.parameters', [p.name for p in study.random])):
        moot = [name for name in names if name in STEERING_MOTION_PARAMETERS]
        if moot:
            raise StudyError(f'{where}.{moot[0]}: plays no part with steering: '
                             f'{study.steering} (the wheels take each angle at once); set '
                             'steering: realistic')


def _check_runs(study: Study) -> None:
    """Every run's inputs within range (random draws included), before anything runs."""
    if study.run_count > MAX_RUNS:
        raise StudyError(f'the study expands to {study.run_count} runs; the limit is '
                         f'{MAX_RUNS:,}')
    last_seed = study.seed + study.points * study.seeds_per_point
    if last_seed > MAX_SEED:
        raise StudyError(f'seed: {study.seed} + the runs\' {study.points * study.seeds_per_point} '
                         f'seeds passes {MAX_SEED} (a ROS integer parameter)')
    described = {p.name: f'random.parameters.{p.name} ({p.description})' for p in study.random}
    checked: set[int] = set()
    for row in study.runs():
        if row['point'] in checked:
            continue
        checked.add(row['point'])
        for name in described:
            try:
                _in_range(f"{described[name]}, draw {row['point'] % study.draws}", name,
                          row[name])
            except StudyError as error:
                raise StudyError(f'{error}: narrow the distribution') from None
        if study.scenario == CLOSED_LOOP and row['timer1_near_s'] > row['timer1_far_s']:
            raise StudyError(f"point {row['point']}: timer1_near_s {row['timer1_near_s']:g} s "
                             f"is longer than timer1_far_s {row['timer1_far_s']:g} s")
        if study.scenario == 'open_loop' and math.hypot(
                row['goal_x_mm'] - row['start_x_mm'], row['goal_y_mm'] - row['start_y_mm']) == 0:
            raise StudyError(f"point {row['point']}: the goal is the start; an open-loop move "
                             'needs a distance')


def load_study(path: Path) -> Study:
    try:
        text = Path(path).read_text(encoding='utf-8')
    except UnicodeDecodeError as error:
        raise StudyError(f'{path}: not UTF-8 text (byte {error.start}); a study file is YAML') \
            from None
    except OSError as error:
        raise StudyError(f'{path}: cannot read the study file ({error.strerror})') from None
    return parse_study(text, str(path))
