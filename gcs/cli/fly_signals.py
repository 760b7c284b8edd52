"""The signals of `fleetplan fly`, handled on the main thread's loop while the plan is flown:
Ctrl-C or SIGTERM aborts (every vehicle lands) and a second one quits at once; SIGUSR1
pauses the flight and SIGUSR2 resumes it, each said on stdout with the flight time."""

from __future__ import annotations

import asyncio
import signal
import sys
from typing import TYPE_CHECKING, Any

from gcs.errors import GcsError

if TYPE_CHECKING:
    from gcs.flight.host.flight_handle import FlightHandle

__all__ = ["FlightSignals"]

#: The signals a flight handles, handed back to their defaults at its end.
SIGNALS = (signal.SIGINT, signal.SIGTERM, signal.SIGUSR1, signal.SIGUSR2)


class FlightSignals:
    """The flight's signals, handled on the running loop from construction until `remove`:
    what they ask of `handle`, and `task` (the flight's record future) cancelled by a second
    interrupt."""

    def __init__(self, handle: FlightHandle, task: asyncio.Future[dict[str, Any]]) -> None:
        self.handle, self.task = handle, task
        self.interrupts = 0
        self.pending: list[asyncio.Future[Any]] = []
        """The aborts, pauses and resumes asked for (held so that they run to the end)."""
        self.loop = asyncio.get_running_loop()
        self.loop.add_signal_handler(signal.SIGINT, self.interrupt)
        self.loop.add_signal_handler(signal.SIGTERM, self.interrupt, "SIGTERM")
        self.loop.add_signal_handler(signal.SIGUSR1, self.pause, False)
        self.loop.add_signal_handler(signal.SIGUSR2, self.pause, True)

    def interrupt(self, name: str = "Ctrl-C") -> None:
        """The first one aborts the flight (every vehicle lands), the second cancels `task`."""
        self.interrupts += 1
        if self.interrupts == 1:
            print(f"\n{name}: aborting, every vehicle lands ({name} again quits at once)",
                  file=sys.stderr, flush=True)
            self.pending.append(asyncio.ensure_future(self.handle.abort(
                "land", f"interrupted ({name})")))
        else:
            self.task.cancel()

    def pause(self, resume: bool) -> None:
        """Pause the flight (or resume it, `resume`), said once it is done."""
        self.pending.append(asyncio.ensure_future(self._pause_or_resume(resume)))

    async def _pause_or_resume(self, resume: bool) -> None:
        """The pause or resume, and the line saying at which flight time (or why not)."""
        try:
            t = await (self.handle.resume() if resume else self.handle.pause())
        except GcsError as exc:
            print(f"cannot {'resume' if resume else 'pause'}: {exc}", file=sys.stderr,
                  flush=True)
            return
        print(f"{'resumed' if resume else 'paused'} at flight time {t:.2f} s "
              f"({'SIGUSR1 pauses' if resume else 'SIGUSR2 resumes'})", flush=True)

    def remove(self) -> None:
        """Hand the signals back to their defaults."""
        for sig in SIGNALS:
            self.loop.remove_signal_handler(sig)
