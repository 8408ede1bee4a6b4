"""A finished study's summary (CSV and markdown) and figure, from its rows alone."""

from __future__ import annotations

import csv
import io
import itertools
from pathlib import Path
from typing import Any

import numpy as np

from omni_micro_studies.inputs import CLOSED_LOOP, PARAMETERS
from omni_micro_studies.spec import Study

MODE_LABELS = {'paper': "paper's rule", 'model': 'model-based', 'servo': 'servo',
               'open_loop': 'open loop'}
MODE_COLOURS = {'paper': 'tab:orange', 'model': 'tab:blue', 'servo': 'tab:red',
                'open_loop': 'tab:green'}


def plotted_metrics(study: Study) -> list[str]:
    """What the summary and the figure show: the loop's accuracy and effort, and its time when
    the study asks for it; an open-loop move's drift."""
    if study.scenario != CLOSED_LOOP:
        return ['drift_um']
    return ['deviation_um', 'periods', *(['sim_time_s'] if 'sim_time_s' in study.metrics
                                        else [])]


def _values(rows: list[dict[str, Any]], column: str) -> np.ndarray:
    return np.array([row[column] for row in rows if row[column] is not None], dtype=float)


def _label(name: str) -> str:
    unit = PARAMETERS[name].unit if name in PARAMETERS else ''
    return f'{name} ({unit})' if unit else name


def summary_rows(study: Study, rows: list[dict[str, Any]]) -> list[dict[str, Any]]:
    """One line per grid point and mode (random draws pooled): counts, medians, spread."""
    groups: dict[tuple, list[dict[str, Any]]] = {}
    for row in rows:
        key = (*(row[name] for name in study.grid), row['mode'])
        groups.setdefault(key, []).append(row)
    lines = []
    for key, members in groups.items():
        line: dict[str, Any] = dict(zip([*study.grid, 'mode'], key, strict=True))
        line['runs'] = len(members)
        line['failed'] = sum(1 for row in members if row['error'] is not None)
        if study.scenario == CLOSED_LOOP:
            line['reached_percent'] = 100.0 * sum(
                row['outcome'] == 'reached' for row in members) / len(members)
        for metric in plotted_metrics(study):
            values = _values(members, metric)
            if values.size:
                line[f'{metric}_median'] = float(np.median(values))
                line[f'{metric}_p95'] = float(np.percentile(values, 95))
                line[f'{metric}_max'] = float(np.max(values))
        lines.append(line)
    return lines


def write_summary(study: Study, rows: list[dict[str, Any]], out: Path) -> str:
    """summary.csv and summary.md in ``out``; returns the markdown table."""
    lines = summary_rows(study, rows)
    columns = list(dict.fromkeys(key for line in lines for key in line))
    buffer = io.StringIO()
    writer = csv.DictWriter(buffer, columns, lineterminator='\n')
    writer.writeheader()
    writer.writerows(lines)
    (out / 'summary.csv').write_text(buffer.getvalue())

    def cell(value: Any) -> str:
        if isinstance(value, float):
            return f'{value:.4g}'
        return MODE_LABELS.get(value, str(value)) if isinstance(value, str) else str(value)

    table = ['| ' + ' | '.join(columns) + ' |', '|' + '---|' * len(columns)]
    table += ['| ' + ' | '.join(cell(line.get(column, '')) for column in columns) + ' |'
              for line in lines]
    failed = sum(line['failed'] for line in lines)
    text = '\n'.join([
        f'# {study.name}', '', study.description, '',
        f'{len(rows)} runs ({study.scenario}, {study.points} points x {study.seeds_per_point} '
        f'seeds x {len(study.modes)} mode(s)); varied: {", ".join(study.swept) or "nothing"}.'
        + (f' {failed} runs failed: their error column says why.' if failed else ''),
        '', *table, ''])
    (out / 'summary.md').write_text(text)
    return text


def write_figure(study: Study, rows: list[dict[str, Any]], path: Path) -> bool:
    """The study's figure: metric against a 1-D grid with its spread, heat maps of a 2-D grid,
    histograms (and scatter against each drawn parameter) of a Monte Carlo. False when a grid
    of three or more dimensions has no figure."""
    import matplotlib

    matplotlib.use('Agg')
    import matplotlib.pyplot as plt

    metrics = plotted_metrics(study)
    usable = [row for row in rows if row['error'] is None]
    if len(study.grid) >= 3:
        return False
    if len(study.grid) == 2:
        fig = _heat_maps(plt, study, usable, metrics)
    elif len(study.grid) == 1:
        fig = _sweep(plt, study, usable, metrics)
    else:
        fig = _monte_carlo(plt, study, usable, metrics)
    fig.suptitle(f'{study.name}: {len(rows)} runs', fontsize=12)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return True


def _sweep(plt: Any, study: Study, rows: list[dict[str, Any]], metrics: list[str]) -> Any:
    (name, values), = study.grid.items()
    fig, axes = plt.subplots(1, len(metrics), figsize=(6.2 * len(metrics), 4.4), squeeze=False)
    for axis, metric in zip(axes[0], metrics, strict=True):
        for mode in study.modes:
            stats = []
            for value in values:
                data = _values([r for r in rows if r[name] == value and r['mode'] == mode],
                               metric)
                stats.append(np.percentile(data, [0, 25, 50, 75, 100]) if data.size
                             else np.full(5, np.nan))
            table = np.array(stats)
            colour = MODE_COLOURS[mode]
            axis.plot(values, table[:, 2], 'o-', color=colour,
                      label=f'{MODE_LABELS[mode]}: median')
            axis.fill_between(values, table[:, 1], table[:, 3], color=colour, alpha=0.25,
                              label='25-75 %')
            axis.plot(values, table[:, 4], 'v', color=colour, alpha=0.6, markersize=4,
                      label='max')
        axis.set(xlabel=_label(name), ylabel=metric, title=f'{metric} vs {name}')
        axis.grid(True, alpha=0.3)
        axis.legend(fontsize=8)
    return fig


def _heat_maps(plt: Any, study: Study, rows: list[dict[str, Any]], metrics: list[str]) -> Any:
    (x_name, x_values), (y_name, y_values) = study.grid.items()
    panels = list(itertools.product(metrics, study.modes))
    fig, axes = plt.subplots(1, len(panels), figsize=(5.8 * len(panels), 4.8), squeeze=False)
    for axis, (metric, mode) in zip(axes[0], panels, strict=True):
        image = np.full((len(y_values), len(x_values)), np.nan)
        for i, y in enumerate(y_values):
            for j, x in enumerate(x_values):
                data = _values([r for r in rows if r[x_name] == x and r[y_name] == y
                                and r['mode'] == mode], metric)
                if data.size:
                    image[i, j] = np.median(data)
        # Cells by index, labelled with the grid's values: a grid need not be evenly spaced.
        mesh = axis.imshow(image, origin='lower', aspect='auto', cmap='viridis')
        fig.colorbar(mesh, ax=axis, label=f'median {metric}')
        if image.size <= 64:
            for (i, j), value in np.ndenumerate(image):
                if np.isfinite(value):
                    axis.text(j, i, f'{value:.3g}', ha='center', va='center', fontsize=8,
                              color='white' if value < np.nanmean(image) else 'black')
        axis.set_xticks(range(len(x_values)), _ticks(x_values))
        axis.set_yticks(range(len(y_values)), _ticks(y_values))
        axis.set(xlabel=_label(x_name), ylabel=_label(y_name),
                 title=f'{metric}, {MODE_LABELS[mode]}')
    return fig


def _ticks(values: list[float]) -> list[str]:
    step = max(1, len(values) // 11)    # at most a dozen labels
    return [f'{value:g}' if index % step == 0 else '' for index, value in enumerate(values)]


def _monte_carlo(plt: Any, study: Study, rows: list[dict[str, Any]],
                 metrics: list[str]) -> Any:
    drawn = [parameter.name for parameter in study.random][:2]
    columns = len(metrics) + len(drawn)
    fig, axes = plt.subplots(1, columns, figsize=(5.2 * columns, 4.2), squeeze=False)
    for axis, metric in zip(axes[0][:len(metrics)], metrics, strict=True):
        everything = _values(rows, metric)
        bins: np.ndarray | int
        if metric == 'periods':
            low, high = (everything.min(), everything.max()) if everything.size else (0, 1)
            bins = np.arange(low - 0.5, high + 1.5)
        else:
            bins = np.histogram_bin_edges(everything, bins=30) if everything.size else 10
        for mode in study.modes:
            data = _values([row for row in rows if row['mode'] == mode], metric)
            label = (f'{MODE_LABELS[mode]}: median {np.median(data):.3g}' if data.size
                     else MODE_LABELS[mode])
            axis.hist(data, bins=bins, alpha=0.6, color=MODE_COLOURS[mode], label=label)
        axis.set(xlabel=metric, ylabel='runs', title=f'{metric}')
        axis.grid(True, alpha=0.3)
        axis.legend(fontsize=8)
    metric = metrics[0]
    for axis, name in zip(axes[0][len(metrics):], drawn, strict=True):
        for mode in study.modes:
            members = [row for row in rows if row['mode'] == mode and row[metric] is not None]
            axis.scatter([row[name] for row in members], [row[metric] for row in members],
                         s=8, alpha=0.6, color=MODE_COLOURS[mode], label=MODE_LABELS[mode])
        axis.set(xlabel=_label(name), ylabel=metric, title=f'{metric} vs {name}')
        axis.grid(True, alpha=0.3)
        axis.legend(fontsize=8)
    return fig

