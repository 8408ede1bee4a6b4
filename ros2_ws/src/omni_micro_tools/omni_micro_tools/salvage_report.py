"""What a salvage of a damaged bag kept and what it lost (:mod:`omni_micro_tools.bag_salvage`
and :mod:`omni_micro_tools.mcap_salvage` fill it in; ``omni-micro bag-recover`` prints it)."""

from __future__ import annotations

from dataclasses import dataclass, field


@dataclass(frozen=True)
class DroppedStretch:
    """Messages a damaged stretch of the file took with it: how many (None: the file no longer
    says) and between which log times (ns; None: the bag's start, or its end)."""

    count: int | None
    from_ns: int | None
    to_ns: int | None

    def said(self) -> str:
        """'12 between 4.200 and 5.380 s', as bag-recover prints it."""
        def when(ns: int | None, otherwise: str) -> str:
            return otherwise if ns is None else f'{ns * 1e-9:.3f} s'
        count = 'an unknown number' if self.count is None else str(self.count)
        return (f'{count} between {when(self.from_ns, "the start")} and '
                f'{when(self.to_ns, "the end")}')


@dataclass
class Recovery:
    """What ``recover`` kept and what it could not."""

    counts: dict[str, int]          # messages kept, per topic
    dropped: int = 0                # messages of damaged chunks, or that did not decode
    undecodable: int = 0            # of those, read whole but not decodable as their type
    damaged_chunks: int = 0         # damaged stretches of the file (a chunk, or more)
    cut_short: bool = False         # the file ends inside a record (a kill, a copy cut short)
    unsure_tail: int = 0            # whole messages of the last RECOVERY_WINDOW_S, left out
    stretches: list[DroppedStretch] = field(default_factory=list)   # where the damage lies

    @property
    def kept(self) -> int:
        return sum(self.counts.values())
