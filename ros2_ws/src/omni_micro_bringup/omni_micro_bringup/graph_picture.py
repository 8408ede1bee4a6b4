"""The node graph as a picture, as rqt_graph draws it: who publishes on the left, the topics (type,
QoS) in the middle, who subscribes on the right, an arrow per endpoint; drawn with matplotlib
from what :func:`~omni_micro_bringup.graph_description.describe_graph` read."""

from __future__ import annotations

from typing import Any

from omni_micro_bringup.composition import ORCHESTRATOR_NODE
from omni_micro_bringup.graph_description import TopicEndpoints

# What the picture calls the orchestrator's node: the command that started the graph.
ORCHESTRATOR_LABEL = 'omni-micro (orchestration)'


def nodes_of(topics: list[TopicEndpoints]) -> list[str]:
    """Every node that publishes or subscribes one of ``topics``, by name."""
    return sorted({e.node for t in topics for e in (*t.publishers, *t.subscribers)})


def _label(node: str) -> str:
    return ORCHESTRATOR_LABEL if node == ORCHESTRATOR_NODE else node


def _qos(topic: TopicEndpoints) -> str:
    offered = topic.publishers or topic.subscribers
    kinds = sorted({f'{e.reliability}, {e.durability}' for e in offered})
    return '; '.join(kinds)


def draw(topics: list[TopicEndpoints], fmt: str) -> bytes:
    """The picture: publishers | topics (type, QoS) | subscribers, an arrow per endpoint."""
    import io

    import matplotlib

    matplotlib.use('Agg')
    import matplotlib.pyplot as plt

    # Text stays text in an SVG: searchable, and a tenth of the size of glyphs drawn as paths.
    plt.rcParams['svg.fonttype'] = 'none'

    publishers = sorted({e.node for t in topics for e in t.publishers})
    subscribers = sorted({e.node for t in topics for e in t.subscribers})
    rows = max(len(topics), len(publishers), len(subscribers), 1)
    figure, axes = plt.subplots(figsize=(15.0, 0.55 * rows + 1.2))
    axes.set_xlim(-0.1, 3.1)
    axes.set_ylim(-0.8, rows)
    axes.axis('off')

    def spread(count: int) -> list[float]:
        step = rows / max(count, 1)
        return [rows - step * (index + 0.5) for index in range(count)]

    left = dict(zip(publishers, spread(len(publishers)), strict=True))
    right = dict(zip(subscribers, spread(len(subscribers)), strict=True))
    middle = {t.topic: y for t, y in zip(topics, spread(len(topics)), strict=True)}
    colours = plt.get_cmap('tab20')
    node_box = {'boxstyle': 'round,pad=0.3', 'facecolor': '#dbe9f6', 'edgecolor': '#3b6ea5'}
    topic_box = {'boxstyle': 'square,pad=0.25', 'facecolor': '#fdf3d8', 'edgecolor': '#b58a00'}
    for index, topic in enumerate(topics):
        colour = colours(index % 20)
        y = middle[topic.topic]
        for endpoint in topic.publishers:
            axes.annotate('', xy=(0.97, y), xytext=(0.42, left[endpoint.node]),
                          arrowprops={'arrowstyle': '->', 'color': colour, 'lw': 0.9})
        for endpoint in topic.subscribers:
            axes.annotate('', xy=(2.58, right[endpoint.node]), xytext=(2.03, y),
                          arrowprops={'arrowstyle': '->', 'color': colour, 'lw': 0.9})
        axes.text(1.5, y, f'{topic.topic}\n{topic.msgtype}  [{_qos(topic)}]', ha='center',
                  va='center', fontsize=7, bbox=topic_box)
    for node, y in left.items():
        axes.text(0.2, y, _label(node), ha='center', va='center', fontsize=8, bbox=node_box)
    for node, y in right.items():
        axes.text(2.8, y, _label(node), ha='center', va='center', fontsize=8, bbox=node_box)
    axes.text(0.2, rows - 0.1 + 0.5, 'publishes', ha='center', fontsize=9, weight='bold')
    axes.text(1.5, rows - 0.1 + 0.5, 'topic, type [QoS]', ha='center', fontsize=9,
              weight='bold')
    axes.text(2.8, rows - 0.1 + 0.5, 'subscribes', ha='center', fontsize=9, weight='bold')
    axes.set_ylim(-0.8, rows + 0.9)
    buffer = io.BytesIO()
    # No date in an SVG: the same graph gives the same file.
    metadata: dict[str, Any] = {'Date': None} if fmt == 'svg' else {}
    figure.savefig(buffer, format=fmt, bbox_inches='tight', metadata=metadata)
    plt.close(figure)
    return buffer.getvalue()
