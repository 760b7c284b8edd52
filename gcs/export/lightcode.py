"""Skybrush's light bytecode: a drone's light program as the bytes a ``.skyc`` carries.

The format, as Skybrush's public sources define it (libskybrush ``src/lights/commands.h`` and
``executor.cpp``, pyledctrl's compiler): a stream of one-byte opcodes, each followed by its
arguments; colours are three bytes (red, green, blue); every duration is an unsigned varint
(7 bits a byte, least significant group first, the high bit set on every byte but the last)
counting frames of 1/50 s. ``SET_COLOR r g b d`` shows the colour at once and waits d;
``FADE_TO_COLOR r g b d`` fades linearly from the current colour to it over d; ``SLEEP d``
waits; ``END`` stops (the last colour stays). A program starts dark at the show's time 0.

`encode` writes a list of `Change` with these four instructions only (absolute times are
rounded to frames first, so rounding never accumulates); `decode` reads a program back into
the same changes (also the grey/black/white variants, NOP, WAIT_UNTIL and LOOPs a show
tool may write), and `colors_at` samples changes at any times.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from dataclasses import dataclass

import numpy as np

from planner.types import FloatArray

__all__ = ["FPS", "Change", "LightCodeError", "colors_at", "decode", "encode"]

#: Frames per second of every duration in the bytecode.
FPS = 50
END, NOP, SLEEP, WAIT_UNTIL = 0x00, 0x01, 0x02, 0x03
SET_COLOR, SET_GRAY, SET_BLACK, SET_WHITE = 0x04, 0x05, 0x06, 0x07
FADE_TO_COLOR, FADE_TO_GRAY, FADE_TO_BLACK, FADE_TO_WHITE = 0x08, 0x09, 0x0A, 0x0B
LOOP_BEGIN, LOOP_END, RESET_CLOCK = 0x0C, 0x0D, 0x0E
SET_PYRO, SET_PYRO_ALL = 0x14, 0x15
#: Most instructions one program may run when decoded (bounds loops in a hostile file).
MAX_STEPS = 1_000_000
BLACK = (0, 0, 0)
WHITE = (255, 255, 255)


class LightCodeError(ValueError):
    """A light program that cannot be read: `offset` is the byte where reading failed."""

    def __init__(self, offset: int, reason: str) -> None:
        super().__init__(f"byte {offset}: {reason}")
        self.offset = offset
        self.reason = reason


@dataclass(frozen=True)
class Change:
    """The lights reach `color` linearly from `start` to `end` (s from the show's start),
    from whatever they showed at `start`; `start == end` sets it at once."""

    start: float
    end: float
    color: tuple[int, int, int]


def _varint(value: int) -> bytes:
    out = bytearray()
    while True:
        low = value & 0x7F
        value >>= 7
        if value:
            out.append(low | 0x80)
        else:
            out.append(low)
            return bytes(out)


def _frame(seconds: float) -> int:
    return max(0, round(seconds * FPS))


def encode(changes: Iterable[Change], end: float) -> bytes:
    """The program of `changes` (in time order), ending with END at `end` (s)."""
    out = bytearray()
    cursor = 0
    for change in changes:
        first, last = _frame(change.start), max(_frame(change.start), _frame(change.end))
        if first > cursor:
            out += bytes([SLEEP]) + _varint(first - cursor)
        cursor = max(cursor, first)
        opcode = FADE_TO_COLOR if last > cursor else SET_COLOR
        out += bytes([opcode, *change.color]) + _varint(max(last - cursor, 0))
        cursor = max(cursor, last)
    if _frame(end) > cursor:
        out += bytes([SLEEP]) + _varint(_frame(end) - cursor)
    out.append(END)
    return bytes(out)


class _Reader:
    def __init__(self, data: bytes) -> None:
        self.data = data
        self.at = 0

    def byte(self) -> int:
        if self.at >= len(self.data):
            raise LightCodeError(self.at, "the program ends inside an instruction")
        value = self.data[self.at]
        self.at += 1
        return value

    def varint(self) -> int:
        value, shift = 0, 0
        while True:
            byte = self.byte()
            value |= (byte & 0x7F) << shift
            if not byte & 0x80:
                return value
            shift += 7
            if shift > 35:
                raise LightCodeError(self.at, "a duration longer than 5 bytes")

    def rgb(self) -> tuple[int, int, int]:
        return self.byte(), self.byte(), self.byte()


def decode(data: bytes, until: float = float("inf")) -> list[Change]:
    """The changes a program makes up to `until` (s), in time order; `LightCodeError` for a
    program that cannot be read (unknown opcode, truncated, jumps, too long)."""
    read = _Reader(data)
    changes: list[Change] = []
    clock = 0
    loops: list[list[int]] = []  # [address after LOOP_BEGIN, iterations left (0: forever)]
    for _ in range(MAX_STEPS):
        if read.at >= len(data) or clock > until * FPS:
            return changes
        start = read.at
        op = read.byte()
        color: tuple[int, int, int] | None = None
        fade = False
        if op == END:
            return changes
        if op in (NOP, RESET_CLOCK):
            continue
        if op in (SET_PYRO, SET_PYRO_ALL):
            read.byte()
            continue
        if op == SLEEP:
            clock += read.varint()
            continue
        if op == WAIT_UNTIL:
            clock = max(clock, read.varint())
            continue
        if op in (SET_COLOR, FADE_TO_COLOR):
            color = read.rgb()
        elif op in (SET_GRAY, FADE_TO_GRAY):
            grey = read.byte()
            color = (grey, grey, grey)
        elif op in (SET_BLACK, FADE_TO_BLACK):
            color = BLACK
        elif op in (SET_WHITE, FADE_TO_WHITE):
            color = WHITE
        elif op == LOOP_BEGIN:
            loops.append([read.at + 1, read.byte()])
            continue
        elif op == LOOP_END:
            if not loops:
                raise LightCodeError(start, "LOOP_END without LOOP_BEGIN")
            loop = loops[-1]
            if loop[1] == 1:
                loops.pop()
            else:
                loop[1] = max(loop[1] - 1, 0)
                read.at = loop[0]
            continue
        else:
            raise LightCodeError(start, f"opcode 0x{op:02x} is not a light instruction this "
                                        f"reader follows (jumps, channels)")
        fade = op in (FADE_TO_COLOR, FADE_TO_GRAY, FADE_TO_BLACK, FADE_TO_WHITE)
        frames = read.varint()
        if fade:
            changes.append(Change(clock / FPS, (clock + frames) / FPS, color))
        else:
            changes.append(Change(clock / FPS, clock / FPS, color))
        clock += frames
    raise LightCodeError(read.at, f"runs more than {MAX_STEPS} instructions")


def colors_at(changes: Sequence[Change], times: FloatArray) -> FloatArray:
    """The colour (M, 3), 0..255 as floats, at each of `times` (s): dark before the first
    change, each fade linear from the colour shown when it starts."""
    times = np.asarray(times, dtype=float)
    out = np.zeros((len(times), 3))
    current = np.zeros(3)
    for change in changes:
        target = np.array(change.color, dtype=float)
        if change.end > change.start:
            inside = (times >= change.start) & (times < change.end)
            u = ((times[inside] - change.start) / (change.end - change.start))[:, None]
            out[inside] = current + u * (target - current)
        out[times >= change.end] = target
        current = target
    return out
