"""Persistence of missions, plans and flight records (SQLAlchemy 2; SQLite or PostgreSQL).

Long: the two tables and their queries, one transaction each.

Two tables: `missions` (the scenario, the planning status and, once planned, the Plan JSON) and
`executions` (the flights of a mission: status, events, summary and the flight record; the
table keeps its first name so existing databases load). JSON
documents are stored as text exactly as produced: a 64-vehicle plan is several megabytes, and
keeping it as text lets the API send it without parsing and re-serialising it on every request.

The store is synchronous; the API calls it from worker threads, never on the event loop.
Tables are created on first use (`create_all`); there is no migration tool yet, so a schema
change means a new database file.
"""

from __future__ import annotations

import json
import uuid
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from datetime import UTC, datetime
from typing import Any, cast

from sqlalchemy import (
    DateTime,
    ForeignKey,
    Integer,
    String,
    Text,
    create_engine,
    event,
    func,
    select,
    update,
)
from sqlalchemy.dialects.postgresql import JSON as PG_JSON
from sqlalchemy.engine import CursorResult, Engine, Result
from sqlalchemy.orm import (
    DeclarativeBase,
    Mapped,
    Session,
    defer,
    mapped_column,
    sessionmaker,
)
from sqlalchemy.sql.elements import ColumnElement

from gcs.documents import FlightEvent, current_events
from gcs.service.statuses import FLIGHT_ACTIVE, FlightStatus, MissionStatus

__all__ = [
    "FLIGHT_ACTIVE",
    "FlightRow",
    "MissionRow",
    "Store",
    "new_mission_id",
]


def _now() -> datetime:
    return datetime.now(UTC)


def _new_id() -> str:
    return uuid.uuid4().hex[:12]


def new_mission_id() -> str:
    """A fresh mission id (the planning queue names a mission before it is stored)."""
    return _new_id()


class _Base(DeclarativeBase):
    pass


class _Mission(_Base):
    __tablename__ = "missions"

    id: Mapped[str] = mapped_column(String(32), primary_key=True)
    name: Mapped[str] = mapped_column(String(200))
    status: Mapped[str] = mapped_column(String(16), index=True)
    created_at: Mapped[datetime] = mapped_column(DateTime(timezone=True))
    updated_at: Mapped[datetime] = mapped_column(DateTime(timezone=True))
    vehicle_count: Mapped[int] = mapped_column(Integer)
    steps: Mapped[int] = mapped_column(Integer)
    dt: Mapped[str] = mapped_column(String(32))
    scenario_json: Mapped[str] = mapped_column(Text)
    plan_status: Mapped[str | None] = mapped_column(String(32), nullable=True)
    plan_ok: Mapped[int | None] = mapped_column(Integer, nullable=True)
    plan_json: Mapped[str | None] = mapped_column(Text, nullable=True)
    error_json: Mapped[str | None] = mapped_column(Text, nullable=True)


class _Flight(_Base):
    __tablename__ = "executions"  # the flights' table, under its first name

    id: Mapped[str] = mapped_column(String(32), primary_key=True)
    mission_id: Mapped[str] = mapped_column(
        String(32), ForeignKey("missions.id", ondelete="CASCADE"), index=True
    )
    status: Mapped[str] = mapped_column(String(16), index=True)
    created_at: Mapped[datetime] = mapped_column(DateTime(timezone=True))
    finished_at: Mapped[datetime | None] = mapped_column(DateTime(timezone=True), nullable=True)
    fleet: Mapped[str] = mapped_column(String(200))
    summary_json: Mapped[str | None] = mapped_column(Text, nullable=True)
    events_json: Mapped[str] = mapped_column(Text, default="[]")
    record_json: Mapped[str | None] = mapped_column(Text, nullable=True)
    error: Mapped[str | None] = mapped_column(Text, nullable=True)


@dataclass(frozen=True)
class MissionRow:
    """A mission as stored; `plan_json` is the Plan JSON text (None until planned)."""

    id: str
    name: str
    status: MissionStatus
    created_at: datetime
    updated_at: datetime
    vehicle_count: int
    steps: int
    dt: float
    scenario: dict[str, Any]
    plan_status: str | None
    plan_ok: bool | None
    error: dict[str, Any] | None
    plan_json: str | None = None

    def summary(self) -> dict[str, Any]:
        """The JSON-friendly fields every listing shows (no scenario, no plan)."""
        return {
            "id": self.id,
            "name": self.name,
            "status": self.status,
            "created_at": self.created_at.isoformat(),
            "updated_at": self.updated_at.isoformat(),
            "vehicle_count": self.vehicle_count,
            "steps": self.steps,
            "dt": self.dt,
            "horizon_s": self.steps * self.dt,
            "plan_status": self.plan_status,
            "plan_ok": self.plan_ok,
            "error": self.error,
        }


@dataclass(frozen=True)
class FlightRow:
    """One flight of a mission as stored."""

    id: str
    mission_id: str
    status: FlightStatus
    created_at: datetime
    finished_at: datetime | None
    fleet: str
    summary: dict[str, Any] | None
    events: list[FlightEvent]
    error: str | None
    has_record: bool
    record_json: str | None = None
    event_count: int | None = None
    """How many events are stored, when `events` were not loaded (a listed summary)."""

    def to_dict(self) -> dict[str, Any]:
        return {
            "id": self.id,
            "mission_id": self.mission_id,
            "status": self.status,
            "created_at": self.created_at.isoformat(),
            "finished_at": None if self.finished_at is None else self.finished_at.isoformat(),
            "fleet": self.fleet,
            "summary": self.summary,
            "events": self.events,
            "error": self.error,
            "has_record": self.has_record,
        }


def _aware(value: datetime) -> datetime:
    """SQLite hands back naive datetimes; everything here is UTC."""
    return value if value.tzinfo is not None else value.replace(tzinfo=UTC)


def _mission_row(m: _Mission, *, with_plan: bool) -> MissionRow:
    return MissionRow(
        id=m.id,
        name=m.name,
        status=MissionStatus(m.status),
        created_at=_aware(m.created_at),
        updated_at=_aware(m.updated_at),
        vehicle_count=m.vehicle_count,
        steps=m.steps,
        dt=float(m.dt),
        scenario=json.loads(m.scenario_json),
        plan_status=m.plan_status,
        plan_ok=None if m.plan_ok is None else bool(m.plan_ok),
        error=None if m.error_json is None else json.loads(m.error_json),
        plan_json=m.plan_json if with_plan else None,
    )


def _flight_row(
    e: _Flight, *, with_record: bool = False, has_record: bool | None = None,
    event_count: int | None = None,
) -> FlightRow:
    """The row as stored; with `event_count` given its events are not read (left empty)."""
    return FlightRow(
        id=e.id,
        mission_id=e.mission_id,
        status=FlightStatus(e.status),
        created_at=_aware(e.created_at),
        finished_at=None if e.finished_at is None else _aware(e.finished_at),
        fleet=e.fleet,
        summary=None if e.summary_json is None else json.loads(e.summary_json),
        events=([] if event_count is not None
                else current_events(json.loads(e.events_json or "[]"))),
        error=e.error,
        has_record=e.record_json is not None if has_record is None else has_record,
        record_json=e.record_json if with_record else None,
        event_count=event_count,
    )


def _changed(result: Result[Any]) -> int:
    """Rows an UPDATE changed: its result is a `CursorResult` (`Session.execute` is typed
    as returning any `Result`)."""
    return int(cast("CursorResult[Any]", result).rowcount or 0)


def _sqlite_pragmas(dbapi_connection: Any, _record: Any) -> None:
    cursor = dbapi_connection.cursor()
    # WAL lets readers proceed while a plan is being written; foreign keys make the
    # executions' ON DELETE CASCADE work.
    cursor.execute("PRAGMA journal_mode=WAL")
    cursor.execute("PRAGMA foreign_keys=ON")
    cursor.execute("PRAGMA busy_timeout=5000")
    cursor.close()


class Store:
    """Missions and flights in a SQL database named by a SQLAlchemy URL."""

    def __init__(self, url: str) -> None:
        connect_args: dict[str, Any] = {}
        if url.startswith("sqlite"):
            connect_args["check_same_thread"] = False
        self.engine: Engine = create_engine(url, connect_args=connect_args)
        if self.engine.dialect.name == "sqlite":
            event.listen(self.engine, "connect", _sqlite_pragmas)
        _Base.metadata.create_all(self.engine)
        self._sessions = sessionmaker(self.engine, expire_on_commit=False)

    def close(self) -> None:
        self.engine.dispose()

    def check_writable(self) -> None:
        """Raise (SQLAlchemyError) unless a row can be written: a mission is inserted and
        rolled back, so a read-only file or a full disk shows at start, not on first use."""
        with self._sessions() as session:
            now = _now()
            session.add(_Mission(id="_probe", name="", status="failed", created_at=now,
                                 updated_at=now, vehicle_count=0, steps=0, dt="0",
                                 scenario_json="{}"))
            session.flush()
            session.rollback()

    @contextmanager
    def _session(self) -> Iterator[Session]:
        with self._sessions.begin() as session:
            yield session

    # ------------------------------------------------------------------ missions

    def create_mission(self, scenario: dict[str, Any], mission_id: str | None = None
                       ) -> MissionRow:
        """Store a validated scenario (with defaults filled in) as a mission being planned,
        under `mission_id` (default: a fresh one)."""
        now = _now()
        mission = _Mission(
            id=mission_id or _new_id(),
            name=str(scenario["name"])[:200],
            status=MissionStatus.PLANNING,
            created_at=now,
            updated_at=now,
            vehicle_count=len(scenario["vehicles"]),
            steps=scenario["steps"] if isinstance(scenario["steps"], int) else 0,
            dt=repr(float(scenario["dt"])),
            scenario_json=json.dumps(scenario),
        )
        with self._session() as session:
            session.add(mission)
            session.flush()
            return _mission_row(mission, with_plan=False)

    def get_mission(self, mission_id: str, *, with_plan: bool = False) -> MissionRow | None:
        with self._session() as session:
            mission = session.get(_Mission, mission_id)
            return None if mission is None else _mission_row(mission, with_plan=with_plan)

    def list_missions(self, *, limit: int = 100, offset: int = 0) -> tuple[list[MissionRow], int]:
        """Newest first, without plans; also returns the total count."""
        columns = [c for c in _Mission.__table__.columns if c.name != "plan_json"]
        with self._session() as session:
            total = session.scalar(select(func.count()).select_from(_Mission)) or 0
            rows = session.execute(
                select(*columns)
                .order_by(_Mission.created_at.desc(), _Mission.id)
                .limit(limit)
                .offset(offset)
            ).all()
            missions = [_mission_row(_Mission(**row._mapping), with_plan=False) for row in rows]
        return missions, int(total)

    def finish_planning(
        self, mission_id: str, *, plan_json: str, plan_status: str, plan_ok: bool,
        steps: int | None = None,
    ) -> bool:
        """Record a plan, and its `steps` when the planner chose them (`steps: "auto"`, a
        stored 0); False if the mission was deleted meanwhile."""
        return self._update_mission(
            mission_id,
            status=MissionStatus.PLANNED,
            plan_json=plan_json,
            plan_status=plan_status,
            plan_ok=int(plan_ok),
            **({} if steps is None else {"steps": steps}),
        )

    def fail_planning(self, mission_id: str, error: dict[str, Any]) -> bool:
        """Record why planning failed (`error` has `field`/`reason` or `reason`)."""
        return self._update_mission(
            mission_id, status=MissionStatus.FAILED, error_json=json.dumps(error)
        )

    def fail_stale_planning(self, mission_id: str, error: dict[str, Any]) -> bool:
        """Mark one mission failed if it is still `planning` (no job holds it); False if it
        is not (planned, failed or deleted meanwhile)."""
        with self._session() as session:
            result = session.execute(
                update(_Mission)
                .where(_Mission.id == mission_id, _Mission.status == MissionStatus.PLANNING)
                .values(status=MissionStatus.FAILED, error_json=json.dumps(error),
                        updated_at=_now())
            )
            return _changed(result) > 0

    def fail_unfinished_planning(self, reason: str) -> int:
        """Mark missions left `planning` (by a stopped server) as failed; returns how many."""
        with self._session() as session:
            result = session.execute(
                update(_Mission)
                .where(_Mission.status == MissionStatus.PLANNING)
                .values(
                    status=MissionStatus.FAILED,
                    error_json=json.dumps({"field": None, "reason": reason}),
                    updated_at=_now(),
                )
            )
            return _changed(result)

    def _update_mission(self, mission_id: str, **values: Any) -> bool:
        with self._session() as session:
            result = session.execute(
                update(_Mission)
                .where(_Mission.id == mission_id)
                .values(updated_at=_now(), **values)
            )
            return _changed(result) > 0

    def delete_mission(self, mission_id: str) -> bool:
        """Delete a mission and its flights; False if there was none."""
        with self._session() as session:
            mission = session.get(_Mission, mission_id)
            if mission is None:
                return False
            # Explicit, so the cascade does not depend on the backend's foreign-key support.
            for flight in session.scalars(
                select(_Flight).where(_Flight.mission_id == mission_id)
            ):
                session.delete(flight)
            session.delete(mission)
            return True

    # ------------------------------------------------------------------ flights

    def create_flight(self, mission_id: str, fleet: str) -> FlightRow:
        flight = _Flight(
            id=_new_id(),
            mission_id=mission_id,
            status=FlightStatus.STARTING,
            created_at=_now(),
            fleet=fleet[:200],
            events_json="[]",
        )
        with self._session() as session:
            session.add(flight)
            session.flush()
            return _flight_row(flight)

    def get_flight(self, flight_id: str, *, with_record: bool = False) -> FlightRow | None:
        with self._session() as session:
            flight = session.get(_Flight, flight_id)
            return None if flight is None else _flight_row(flight, with_record=with_record)

    def list_flights(self, mission_id: str | None = None) -> list[FlightRow]:
        """Newest first, optionally of one mission (records are not loaded)."""
        query = (
            select(_Flight, _Flight.record_json.is_not(None))
            .options(defer(_Flight.record_json))
            .order_by(_Flight.created_at.desc(), _Flight.id)
        )
        if mission_id is not None:
            query = query.where(_Flight.mission_id == mission_id)
        with self._session() as session:
            return [
                _flight_row(e, has_record=bool(has))
                for e, has in session.execute(query)
            ]

    def page_flights(self, *, limit: int, offset: int, mission_id: str | None = None
                     ) -> tuple[list[FlightRow], int]:
        """One page of flights newest first, optionally of one mission, and the total count:
        neither records nor events are loaded (a flight's events can be megabytes), the
        database counts the events (`event_count`)."""
        query = (
            select(_Flight, _Flight.record_json.is_not(None), self._event_count())
            .options(defer(_Flight.record_json), defer(_Flight.events_json))
            .order_by(_Flight.created_at.desc(), _Flight.id)
            .limit(limit)
            .offset(offset)
        )
        counted = select(func.count()).select_from(_Flight)
        if mission_id is not None:
            query = query.where(_Flight.mission_id == mission_id)
            counted = counted.where(_Flight.mission_id == mission_id)
        with self._session() as session:
            total = session.scalar(counted) or 0
            rows = [_flight_row(e, has_record=bool(has), event_count=int(count or 0))
                    for e, has, count in session.execute(query)]
        return rows, int(total)

    def _event_count(self) -> ColumnElement[int]:
        """The length of a flight's stored event list, counted in SQL (PostgreSQL's JSON
        function takes a json value, SQLite's the text)."""
        if self.engine.dialect.name == "postgresql":
            return func.json_array_length(_Flight.events_json.cast(PG_JSON))
        return func.json_array_length(_Flight.events_json)

    def update_flight(
        self,
        flight_id: str,
        *,
        status: str | None = None,
        events: list[FlightEvent] | None = None,
        summary: dict[str, Any] | None = None,
        record_json: str | None = None,
        error: str | None = None,
        finished: bool = False,
    ) -> bool:
        values: dict[str, Any] = {}
        if status is not None:
            values["status"] = status
        if events is not None:
            values["events_json"] = json.dumps(events)
        if summary is not None:
            values["summary_json"] = json.dumps(summary)
        if record_json is not None:
            values["record_json"] = record_json
        if error is not None:
            values["error"] = error
        if finished:
            values["finished_at"] = _now()
        if not values:
            return True
        with self._session() as session:
            result = session.execute(
                update(_Flight).where(_Flight.id == flight_id).values(**values)
            )
            return _changed(result) > 0

    def fail_unfinished_flights(self, reason: str) -> int:
        """Flights a stopped server left active: mark them `interrupted`."""
        with self._session() as session:
            result = session.execute(
                update(_Flight)
                .where(_Flight.status.in_(FLIGHT_ACTIVE))
                .values(status=FlightStatus.INTERRUPTED, error=reason, finished_at=_now())
            )
            return _changed(result)
