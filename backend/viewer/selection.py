"""The view selected on a page and in its 3D view, kept in step both ways.

A page makes a pairing key of its own (random, per page load) and puts it in
the 3D view's URL (``?pair=``, passed on by the proxy, ``gate.PAIR_HEADER``).
A row picked in the page's per-view table is posted here under that key and
highlighted in every tab paired with it; a board clicked in 3D is recorded here
and the page, polling, highlights its row. ``seq`` grows with every change, so
a page tells a new choice from one it made itself.
"""
from __future__ import annotations

import threading
from collections import OrderedDict
from dataclasses import dataclass

MAX_PAIRS = 256   # pages remembered; the oldest is forgotten first (a key costs nothing to make)


@dataclass(frozen=True)
class Selected:
    view: str | None = None
    seq: int = 0
    source: str = ""   # "page" or "3d": who chose it


class Selections:
    def __init__(self) -> None:
        self._by_pair: OrderedDict[str, Selected] = OrderedDict()
        self._seq = 0
        self._lock = threading.Lock()

    def get(self, pair: str) -> Selected:
        with self._lock:
            return self._by_pair.get(pair, Selected())

    def choose(self, pair: str, view: str | None, source: str) -> Selected:
        with self._lock:
            self._seq += 1
            chosen = Selected(view, self._seq, source)
            self._by_pair[pair] = chosen
            self._by_pair.move_to_end(pair)
            while len(self._by_pair) > MAX_PAIRS:
                self._by_pair.popitem(last=False)
            return chosen
