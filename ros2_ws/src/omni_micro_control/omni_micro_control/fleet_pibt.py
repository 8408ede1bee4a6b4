"""One step of PIBT (Okumura et al., "Priority inheritance with backtracking for iterative
multi-agent path finding", AIJ 2022) on the fleet's roadmap, as LaCAM's configuration generator
(:mod:`omni_micro_control.fleet_lacam`)."""

from __future__ import annotations

import random
from typing import Protocol

from omni_micro_control.fleet_roadmap import Roadmap


class Search(Protocol):
    """What a step needs of the search it serves."""

    roadmap: Roadmap
    rng: random.Random
    stays: list[int]          # per place: the segment of standing on it

    def distance(self, robot: int, place: int, done: int) -> int: ...

    def done_for_good(self, robot: int, done: int) -> bool: ...


class PibtStep:
    """One step of PIBT (Okumura et al. 2022): robots in turn of priority take the place
    nearest their goal, and a robot in the way is asked to move first (priority inheritance).

    A robot may enter a place another leaves in the same step, the other moving first; the
    order of the step's moves is kept (``first``: who must move before whom) so that, run one
    after another, no move comes within the clearance of a robot standing still. A ring of
    robots each entering the next one's place has no such order and is never made.
    """

    def __init__(self, search: Search, config: tuple[int, ...], done: tuple[int, ...]) -> None:
        self.search = search
        self.roadmap = search.roadmap
        self.config, self.done = config, done
        self.chosen: list[int | None] = [None] * len(config)
        self.first: list[set[int]] = [set() for _ in config]   # who moves before whom
        self.tentative: dict[int, int] = {}
        self.failed = False
        conflicts, stays = self.roadmap.conflicts, search.stays
        # Per segment: the robots standing within clearance of it, and the moves given so far
        # that come within clearance of it.
        self.standing_near: dict[int, list[int]] = {}
        for robot, place in enumerate(self.config):
            for segment in conflicts[stays[place]]:
                self.standing_near.setdefault(segment, []).append(robot)
        self.moves_near: dict[int, list[int]] = {}

    def segment(self, robot: int, place: int) -> int:
        return self.roadmap.segment(self.config[robot], place)

    def order_with(self, robot: int, place: int, other: int, other_place: int
                   ) -> tuple[bool, bool] | None:
        """Whether ``robot``'s move to ``place`` may come before, and after, ``other``'s to
        ``other_place`` (None: the moves keep clear of each other, in any order or at once)."""
        conflicts, stays = self.roadmap.conflicts, self.search.stays
        mine, theirs = self.segment(robot, place), self.segment(other, other_place)
        if theirs not in conflicts[mine]:
            return None
        if place == self.config[robot] or other_place == self.config[other]:
            return False, False          # one stands where the other passes
        before = (stays[self.config[other]] not in conflicts[mine]
                  and stays[place] not in conflicts[theirs])
        after = (stays[self.config[robot]] not in conflicts[theirs]
                 and stays[other_place] not in conflicts[mine])
        return before, after

    def fits(self, robot: int, place: int, in_progress: tuple[int, ...]) -> list | None:
        """The orders ``robot``'s move to ``place`` takes among the moves given, as
        (earlier, later) pairs, each robot before the robots still asking (None: it cannot be
        made). Moves that come within clearance of each other are always ordered."""
        for asking in in_progress:
            order = self.order_with(robot, place, asking, self.tentative[asking])
            if order is not None and not order[0]:
                return None
        before: set[int] = set()       # moves given that must come before robot's
        after: set[int] = set()        # and after it
        either = []
        for other in self.moves_near.get(self.segment(robot, place), ()):
            order = self.order_with(robot, place, other, self.chosen[other])  # type: ignore
            if order is None:
                continue
            first, last = order
            if first and last:
                either.append(other)
            elif first:
                after.add(other)
            elif last:
                before.add(other)
            else:
                return None
        for other in either:
            # Behind it if that closes no ring of turns, else ahead.
            if not any(self._reaches(other, later) for later in after):
                before.add(other)
            else:
                after.add(other)
        if any(earlier == later or self._reaches(earlier, later)
               for earlier in before for later in after):
            return None                # the turns would go round a ring
        return [(other, robot) for other in before] + [(robot, other) for other in after]

    def _reaches(self, source: int, target: int) -> bool:
        """Whether ``target`` moves before ``source`` already, through the turns given."""
        seen, stack = {source}, [source]
        while stack:
            robot = stack.pop()
            if robot == target:
                return True
            for earlier in self.first[robot]:
                if earlier not in seen:
                    seen.add(earlier)
                    stack.append(earlier)
        return False

    def assign(self, robot: int, place: int, edges: list | None = None) -> None:
        self.chosen[robot] = place
        for earlier, later in edges or ():
            self.first[later].add(earlier)
        for segment in self.roadmap.conflicts[self.segment(robot, place)]:
            self.moves_near.setdefault(segment, []).append(robot)

    def pibt(self, robot: int, in_progress: tuple[int, ...] = ()) -> bool:
        """Give ``robot`` the best place it can take (True), or have it stay (False)."""
        search, here = self.search, self.config[robot]
        if search.done_for_good(robot, self.done[robot]):
            choices = [here]
        else:
            choices = [here, *self.roadmap.neighbours[here]]
            search.rng.shuffle(choices)
            done = self.done[robot]
            choices.sort(key=lambda place: search.distance(robot, place, done))
        asking = (*in_progress, robot)
        for place in choices:
            if self.fits(robot, place, in_progress) is None:
                continue
            if place != here:
                self.tentative[robot] = place
                in_the_way = [other for other in self.standing_near.get(
                    self.segment(robot, place), ()) if other != robot]
                if not all(self.chosen[other] is not None or (
                        other not in asking and self.pibt(other, asking))
                        for other in in_the_way):
                    continue
                del self.tentative[robot]
            edges = self.fits(robot, place, in_progress)
            if edges is not None:
                self.assign(robot, place, edges)
                return place != here
        self.tentative.pop(robot, None)
        if self.fits(robot, here, ()) is None:
            self.failed = True        # a move given under the constraint leaves it nowhere
        self.assign(robot, here)
        return False

    def configuration(self) -> tuple[int, ...]:
        """Every robot's place after the step (each has been given one)."""
        places = tuple(place for place in self.chosen if place is not None)
        if len(places) != len(self.chosen):
            raise RuntimeError('a step asked for before every robot was given its place')
        return places

    def ranks(self) -> dict[int, int]:
        """Each moving robot's turn: one more than the latest turn of those it moves after."""
        turns: dict[int, int] = {}

        def turn(robot: int) -> int:
            if robot not in turns:
                turns[robot] = 1 + max((turn(earlier) for earlier in self.first[robot]),
                                       default=-1)
            return turns[robot]

        for robot in range(len(self.config)):
            if self.chosen[robot] != self.config[robot]:
                turn(robot)
        return turns
