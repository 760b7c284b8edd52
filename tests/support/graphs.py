"""Cycles in an import graph (module -> the modules it imports), for the import checks of
the Python packages (tests/test_layout.py) and of the page's scripts (tests/web/test_modules.py)."""

from __future__ import annotations

from collections.abc import Iterable, Mapping

__all__ = ["a_cycle", "cycles", "strongly_connected"]


def strongly_connected(graph: Mapping[str, Iterable[str]]) -> list[list[str]]:
    """The strongly connected components of `graph` with more than one node (Tarjan), each
    sorted; every one of them holds a cycle."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    found: list[list[str]] = []

    def visit(node: str) -> None:
        index[node] = low[node] = len(index)
        stack.append(node)
        on_stack.add(node)
        for succ in graph.get(node, ()):
            if succ not in index:
                visit(succ)
                low[node] = min(low[node], low[succ])
            elif succ in on_stack:
                low[node] = min(low[node], index[succ])
        if low[node] == index[node]:
            component = []
            while True:
                member = stack.pop()
                on_stack.discard(member)
                component.append(member)
                if member == node:
                    break
            if len(component) > 1:
                found.append(sorted(component))

    for node in sorted(graph):
        if node not in index:
            visit(node)
    return sorted(found)


def a_cycle(graph: Mapping[str, Iterable[str]], component: list[str]) -> list[str]:
    """One cycle through the component's first module, as a path that returns to it."""
    start, members = component[0], set(component)
    paths = {start: [start]}
    frontier = [start]
    while frontier:
        nxt = []
        for node in frontier:
            for succ in sorted(graph.get(node, ())):
                if succ == start:
                    return [*paths[node], start]
                if succ in members and succ not in paths:
                    paths[succ] = [*paths[node], succ]
                    nxt.append(succ)
        frontier = nxt
    raise AssertionError(f"{component} is not strongly connected")


def cycles(graph: Mapping[str, Iterable[str]]) -> list[str]:
    """Every import cycle of `graph`, one line per strongly connected component: its modules
    and one cycle through them, as ``a, b: a -> b -> a``."""
    return [f"{', '.join(c)}: {' -> '.join(a_cycle(graph, c))}" for c in strongly_connected(graph)]
