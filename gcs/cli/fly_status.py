"""The live status of `fleetplan fly`: a compact table, one row per vehicle (rich), printed
with the flight's events as they happen (`progress`).

The table is built from `FlightExecutor.snapshot()` alone, so it shows exactly what the
executor knows. Missing or non-finite figures print as "-", never "None" or "nan".
"""

from __future__ import annotations

import asyncio
import math
from collections.abc import Mapping
from typing import TYPE_CHECKING, Any

from rich.console import Console
from rich.live import Live
from rich.table import Table
from rich.text import Text

from gcs.cli.hints import live_warning
from gcs.documents import FlightEvent, FlightSnapshot

if TYPE_CHECKING:
    from gcs.flight.host.flight_handle import FlightHandle

__all__ = ["figure", "header", "progress", "status_table"]

#: Phases shown in colour: trouble in red, done in green, the rest plain.
_PHASE_STYLE = {"faulty": "bold red", "stopped": "red", "landed": "green", "hovering": "yellow"}


def figure(value: float | None, spec: str = ".2f", unit: str = "") -> str:
    """A number for a table: "-" when missing or not finite."""
    if value is None or not math.isfinite(value):
        return "-"
    return f"{value:{spec}}{unit}"


def header(snap: FlightSnapshot) -> str:
    """One line: flight phase, plan time against the horizon (then the time past it), live
    minimum separation."""
    t = snap.get("flight_time")
    horizon = snap.get("horizon")
    if t is None:
        clock = "t -"
    elif horizon is not None and t > horizon:  # holding, landing: the plan itself is done
        clock = f"t {figure(horizon, '.1f')} / {figure(horizon, '.0f')} s +{t - horizon:.1f} s"
    else:
        clock = f"t {figure(t, '.1f')} / {figure(horizon, '.0f')} s"
    return (f"{snap['phase']} · {clock} · min separation "
            f"{figure(snap.get('min_separation_live'), '.2f', ' m')}")


def _link_quality(q: Mapping[str, Any]) -> tuple[Text, str]:
    """The loss over the last seconds (over the whole flight until then; red from 10 %) and
    the latency (`gcs.flight.link.quality`)."""
    loss = q.get("recent_loss_pct")
    loss = q.get("loss_pct") if loss is None else loss
    style = "" if loss is None or loss < 10 else "bold red"
    return Text(figure(loss, ".0f"), style=style), figure(q.get("latency_ms"), ".0f")


def status_table(snap: FlightSnapshot) -> Table:
    """One row per vehicle: phase, PX4 mode, armed, world position, tracking error, link age,
    link loss and latency."""
    table = Table(title=header(snap), title_justify="left", box=None, pad_edge=False,
                  header_style="bold", expand=False)
    for name, justify in (("vehicle", "left"), ("phase", "left"), ("mode", "left"),
                          ("armed", "left"), ("x", "right"), ("y", "right"), ("z", "right"),
                          ("err m", "right"), ("link s", "right"), ("loss %", "right"),
                          ("lat ms", "right"), ("fault", "left")):
        table.add_column(name, justify=justify, no_wrap=True)  # type: ignore[arg-type]
    for v in snap["vehicles"]:
        position = v.get("position") or (None, None, None)
        phase = v.get("phase") or "-"
        table.add_row(
            str(v["id"]),
            Text(phase, style=_PHASE_STYLE.get(phase, "")),
            v.get("mode") or "-",
            "armed" if v.get("armed") else "-",
            *(figure(c, ".1f") for c in position),
            figure(v.get("tracking_error"), ".2f"),
            figure(v.get("link_age"), ".1f"),
            *_link_quality(v.get("link_quality") or {}),
            Text(v.get("fault") or "", style="bold red"),
        )
    return table


async def progress(handle: FlightHandle, events: asyncio.Queue[FlightEvent | None]
                   ) -> None:
    """Events as they happen (from `events`, the queue the flight hands them to), and the
    status table (`status_table`): redrawn in place on a terminal, printed every 5 s
    otherwise (logs stay readable)."""
    console = Console(highlight=False)

    async def print_events() -> None:
        while (event := await events.get()) is not None:
            if event["kind"] in ("statustext", "mode_change") and event["vehicle"]:
                continue
            if live_warning(event, "") is not None:
                continue  # already printed as a warning (stderr)
            who = event["vehicle"] or "fleet"
            console.print(f"  [{event['t']:7.2f}] {who}: {event['kind']} {event['detail']}",
                          markup=False)

    watcher = asyncio.create_task(print_events())
    try:
        if console.is_terminal:
            with Live(status_table(handle.snapshot()), console=console,
                      refresh_per_second=4, transient=False) as live:
                while True:
                    await asyncio.sleep(0.25)
                    live.update(status_table(handle.snapshot()))
        else:
            while True:
                await asyncio.sleep(5.0)
                console.print(status_table(handle.snapshot()))
    finally:
        watcher.cancel()
