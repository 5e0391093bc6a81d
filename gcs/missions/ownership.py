"""Who owns the vehicle link when several service instances share one database: a lease per vehicle.

Two (or more) instances of the service run on one PostgreSQL database for the same vehicle. Exactly one owns
the vehicle link: it talks to the vehicle, flies and records missions. The others are on stand-by: they answer
reads from the shared database, refuse what would need the vehicle (`NotOwnerError`: HTTP 503 naming the
owner), never send the vehicle a byte, and keep trying to take the lease. When the owner dies, a stand-by takes
the lease, starts the link and re-attaches the mission in flight exactly as a restarted service does
(`MissionService`'s `on_acquired`).

The lease is a session-level PostgreSQL advisory lock (`pg_try_advisory_lock(namespace, key)`) held on a
connection of its own: PostgreSQL releases it when the owner's session ends, whether the owner stopped, was
killed or lost its host (the server notices the closed socket at once; a vanished host only after TCP
keepalives give up). The owner sets its instance name as the connection's `application_name`, so a stand-by
can say who owns the link (`pg_locks` joined with `pg_stat_activity`) without a table of its own.

The key is the vehicle's name: `Settings.vehicle_name`, by default the vehicle connection string normalised
(`udpout://127.0.0.1:14540`), so instances configured for the same vehicle compete for the same lease. Name the
vehicle when the instances reach it by different connection strings (different hosts, a radio per host).

An owner that finds its lease gone (its connection broke: the database restarted, the network dropped it)
cannot know whether a stand-by has taken over, so it must stop talking to the vehicle before anyone else
does. It checks once per poll period and ends its process at once (`exit_now`), as Kubernetes' leader
election does: a graceful shutdown would mark the mission in flight failed, and the stand-by that took over
must find it unfinished. The process supervisor (systemd, `buoy-gcs up`) starts it again, as a stand-by. A new
owner waits two poll periods (`TAKEOVER_GRACE_POLLS`) after taking the lease before it opens the link, so
that an old owner still running has noticed and exited. (An old owner frozen longer than that, e.g. stopped
by SIGSTOP, could still send a few messages when it wakes before its next check: the lease has no fencing
token the vehicle could check.)

A fleet (several vehicles, each `SYSID=URL`) is owned whole: the instance's lease is one advisory lock per vehicle,
keyed by `system N` (prefixed by `vehicle_name` when given, so that two fleets with the same system ids can share
a database), all held on the one lease connection and taken all or none (`try_acquire` takes them in key order
and gives back what it took when one is held elsewhere: it never waits, so two instances cannot deadlock). Why
the vehicles and not the fleet missions: a fleet mission's parts are ordinary missions of their vehicles, flown by
whoever owns each vehicle's link, and its coordinator (gcs.missions.fleet_missions) needs every part's link for
the separation and to upload re-shared buoys in flight. The instance that owns all of a fleet's vehicles so owns
its fleet missions too, with no lease of their own that could disagree with the vehicles' leases; it follows
each unfinished fleet mission whose vehicles are all its own, from the coordinator state stored before
(gcs.domain.fleet_coordination). Every vehicle's lease moves with the fleet at a take-over, at once, on the one
session PostgreSQL ends when its owner dies. Per-vehicle keys also keep one vehicle from being owned twice: an
instance configured for a subset of the fleet competes for those vehicles' locks.

With SQLite (one file, one service instance) the instance is always the owner (`SoleLease`).
"""

from __future__ import annotations

import asyncio
import contextlib
import hashlib
import logging
import os
from collections.abc import Awaitable, Callable, Sequence
from enum import StrEnum
from typing import Any, NoReturn, Protocol

import psycopg

from gcs.settings import Settings
from gcs.vehicle.connection import parse_connection

log = logging.getLogger(__name__)

# Advisory locks are one namespace per database: our locks use this first key, the vehicle's hash the second.
LEASE_NAMESPACE = int.from_bytes(b"BUOY") & 0x7FFF_FFFF
QUERY_TIMEOUT_S = 10.0  # wall clock for one lease query; an owner whose check takes longer counts as lost
CONNECT_TIMEOUT_S = 5  # libpq's connect_timeout (whole seconds)
LEASE_LOST_EXIT_CODE = 75  # EX_TEMPFAIL: the supervisor restarts the instance (as a stand-by)
# A new owner waits this many poll periods before it talks to the vehicle: an old owner whose session died while
# its process lives (the database restarted, an operator ended the session) checks its lease once a period and
# exits when it is gone, so by then it has stopped talking to the vehicle.
TAKEOVER_GRACE_POLLS = 2
APPLICATION_NAME_BYTES = 63  # PostgreSQL keeps this much of application_name (NAMEDATALEN - 1)


class Role(StrEnum):
    OWNER = "owner"
    STANDBY = "standby"


class NotOwnerError(RuntimeError):
    """The request needs the vehicle link and this instance is on stand-by (HTTP 503)."""

    def __init__(self, instance: str, owner: str | None) -> None:
        self.instance, self.owner = instance, owner
        holder = f"instance {owner!r}" if owner else "another instance"
        super().__init__(f"this instance ({instance!r}) is on stand-by: {holder} owns the vehicle link; ask it")


def lease_key(vehicle_name: str) -> int:
    """The advisory lock's second key for a vehicle: 31 bits of SHA-256 of its name (positive, so pg_locks shows
    it unchanged in its unsigned objid column)."""
    return int.from_bytes(hashlib.sha256(vehicle_name.encode()).digest()[:4]) & 0x7FFF_FFFF


class Lease(Protocol):
    """The lock a vehicle's owner holds. Every method may be called again after a failure."""

    async def try_acquire(self) -> bool:
        """Take the lease if nobody holds it; True if this instance holds it now."""
        ...

    async def still_held(self) -> bool:
        """The owner's check: False once the lease is gone (its connection broke)."""
        ...

    async def holder(self) -> str | None:
        """The owning instance's name, None when nobody holds the lease (or it cannot be read)."""
        ...

    async def release(self) -> None: ...


class SoleLease:
    """SQLite: one service instance per database file, always the owner."""

    async def try_acquire(self) -> bool:
        return True

    async def still_held(self) -> bool:
        return True

    async def holder(self) -> str | None:
        return None

    async def release(self) -> None:
        return None


class PostgresLease:
    """Session-level advisory locks, one per vehicle, on a connection of its own named after the instance."""

    # the locks this session, or any, holds on the keys: pg_locks shows (int4, int4) keys as classid, objid, 2
    _HELD = (
        "SELECT a.application_name, l.pid = pg_backend_pid() FROM pg_locks l JOIN pg_stat_activity a ON a.pid = l.pid"
        " WHERE l.locktype = 'advisory' AND l.granted AND l.classid = %s::int4::oid AND l.objid::int8 = ANY(%s::int8[])"
        " AND l.objsubid = 2"
    )
    _TRY = "SELECT pg_try_advisory_lock(%s::int4, %s::int4)"
    _UNLOCK = "SELECT pg_advisory_unlock(%s::int4, %s::int4)"

    def __init__(self, url: str, vehicle_names: str | Sequence[str], instance: str) -> None:
        """vehicle_names: the vehicle (one name) or every vehicle of the fleet this instance owns whole."""
        self.url, self.instance = url, instance
        names = [vehicle_names] if isinstance(vehicle_names, str) else list(vehicle_names)
        self.keys = sorted({lease_key(name) for name in names})  # one order for every instance: see try_acquire
        self._connection: psycopg.AsyncConnection | None = None

    async def _connect(self) -> psycopg.AsyncConnection:
        if self._connection is None or self._connection.closed:
            self._connection = await psycopg.AsyncConnection.connect(
                self.url,
                autocommit=True,
                application_name=self.instance.encode()[:APPLICATION_NAME_BYTES].decode(errors="ignore"),
                connect_timeout=CONNECT_TIMEOUT_S,
                # a dead database host is noticed within ~20 s instead of the kernel's two hours
                keepalives=1,
                keepalives_idle=10,
                keepalives_interval=5,
                keepalives_count=2,
            )
        return self._connection

    async def _query(self, sql: str, parameters: tuple[Any, ...]) -> list[tuple[Any, ...]]:
        """Run one query on the lease connection; a broken or slow connection is closed (the locks with it)."""
        try:
            connection = await self._connect()
            async with asyncio.timeout(QUERY_TIMEOUT_S):
                cursor = await connection.execute(sql, parameters)
            return await cursor.fetchall()
        except (psycopg.Error, OSError, TimeoutError):
            await self._drop()
            raise

    async def _drop(self) -> None:
        connection, self._connection = self._connection, None
        if connection is not None:
            with contextlib.suppress(psycopg.Error, OSError):
                await connection.close()

    async def try_acquire(self) -> bool:
        """Every vehicle's lock or none: in key order (every instance the same), giving back those taken when one
        is held elsewhere. pg_try_advisory_lock never waits, so instances with overlapping fleets cannot deadlock."""
        taken: list[int] = []
        try:
            for key in self.keys:
                if not (await self._query(self._TRY, (LEASE_NAMESPACE, key)))[0][0]:
                    for held in taken:
                        await self._query(self._UNLOCK, (LEASE_NAMESPACE, held))
                    return False
                taken.append(key)
        except (psycopg.Error, OSError, TimeoutError) as error:  # the connection is closed: its locks are gone
            log.warning("vehicle lease: cannot reach the database (%s); trying again", error)
            return False
        return True

    async def still_held(self) -> bool:
        try:
            rows = await self._query(self._HELD, (LEASE_NAMESPACE, self.keys))
        except (psycopg.Error, OSError, TimeoutError) as error:
            log.error("vehicle lease: the lease connection failed (%s)", error)
            return False
        return sum(bool(ours) for _, ours in rows) == len(self.keys)  # every vehicle's, on this session

    async def holder(self) -> str | None:
        try:
            rows = await self._query(self._HELD, (LEASE_NAMESPACE, self.keys))
        except (psycopg.Error, OSError, TimeoutError):
            return None
        return rows[0][0] if rows else None

    async def release(self) -> None:
        """Unlock, then close the lease connection (a session's end releases its locks too, but only once the
        server has noticed: unlocking first frees the lease before this returns)."""
        if self._connection is not None:
            with contextlib.suppress(psycopg.Error, OSError, TimeoutError):
                for key in self.keys:
                    await self._query(self._UNLOCK, (LEASE_NAMESPACE, key))
        await self._drop()


def exit_now() -> NoReturn:
    """Lease lost: end the process at once, writing nothing (see the module doc)."""
    log.critical(
        "vehicle lease lost: exiting (code %d) so that only the new owner talks to the vehicle", LEASE_LOST_EXIT_CODE
    )
    logging.shutdown()
    os._exit(LEASE_LOST_EXIT_CODE)


class Ownership:
    """This instance's role for one vehicle, kept by polling the lease every `poll_s` (wall clock).

    `start(on_acquired)` tries once at once (so an instance alone on the database owns the link before it
    serves) and then keeps polling in the background: a stand-by tries to take the lease, an owner checks it
    still holds it and calls `on_lost` when it does not."""

    def __init__(
        self,
        lease: Lease,
        instance: str,
        poll_s: float,
        on_lost: Callable[[], None] = exit_now,
        grace_s: float = 0.0,
    ) -> None:
        self.lease, self.instance, self.poll_s, self.on_lost = lease, instance, poll_s, on_lost
        self.grace_s = grace_s  # wall seconds between taking the lease and the first byte to the vehicle
        self.role = Role.STANDBY
        self.owner: str | None = None  # the owning instance's name, as last read
        self._task: asyncio.Task | None = None

    @property
    def shared(self) -> bool:
        """Whether other instances can take the vehicle link over (the lease lives in a shared database)."""
        return not isinstance(self.lease, SoleLease)

    @property
    def is_owner(self) -> bool:
        return self.role == Role.OWNER

    def ensure_owner(self) -> None:
        """Raise NotOwnerError on a stand-by."""
        if not self.is_owner:
            raise NotOwnerError(self.instance, self.owner)

    def as_dict(self) -> dict[str, Any]:
        """What GET /vehicle and /ws say about the link's ownership."""
        return {"role": self.role, "instance": self.instance, "owner": self.owner}

    async def start(self, on_acquired: Callable[[], Awaitable[None]]) -> None:
        """Become the owner now if the lease is free (awaiting on_acquired), then keep polling in the background."""
        if await self._take(on_acquired):
            log.info("vehicle lease: %s owns the vehicle link", self.instance)
        else:
            log.warning("vehicle lease: on stand-by, %s owns the vehicle link", self.owner or "another instance")
        self._task = asyncio.create_task(self._keep(on_acquired), name="vehicle-lease")

    async def stop(self) -> None:
        """Stop polling (the lease stays held until `release`: stop the link in between)."""
        if self._task is not None:
            self._task.cancel()
            with contextlib.suppress(asyncio.CancelledError):
                await self._task
            self._task = None

    async def release(self) -> None:
        await self.lease.release()
        self.role = Role.STANDBY

    async def _take(self, on_acquired: Callable[[], Awaitable[None]]) -> bool:
        if not await self.lease.try_acquire():
            self.owner = await self.lease.holder()
            return False
        await asyncio.sleep(self.grace_s)
        await on_acquired()  # the link is up and the mission in flight re-attached before the first request
        self.role, self.owner = Role.OWNER, self.instance
        return True

    async def _keep(self, on_acquired: Callable[[], Awaitable[None]]) -> None:
        while True:
            await asyncio.sleep(self.poll_s)
            if self.is_owner:
                if not await self.lease.still_held():
                    self.on_lost()
                    return
                continue
            try:
                if await self._take(on_acquired):
                    log.warning("vehicle lease: %s took over the vehicle link", self.instance)
            except Exception:  # holding the lease without a working link would keep every stand-by out
                log.exception("vehicle lease: taking over the vehicle link failed")
                self.on_lost()
                return


def lease_names(settings: Settings) -> list[str]:
    """The names of the vehicles whose leases this instance takes: its one vehicle's (`vehicle_name`, else its
    connection string normalised), or each of its fleet's by system id (`system N`, after `vehicle_name/` when
    given): a fleet's vehicles keep distinct system ids (PX4's MAV_SYS_ID) whatever connection reaches them."""
    if len(settings.vehicles) < 2:
        return [settings.vehicle_name or str(parse_connection(settings.vehicle_url))]
    prefix = f"{settings.vehicle_name}/" if settings.vehicle_name else ""
    return [f"{prefix}system {sysid}" for sysid, _ in settings.fleet]


def ownership_for(settings: Settings) -> Ownership:
    """On a PostgreSQL database, a lease shared with the other instances there; on SQLite, the sole owner."""
    if settings.db is None:
        return Ownership(SoleLease(), settings.instance_name, settings.lease_poll_s)
    lease = PostgresLease(settings.db, lease_names(settings), settings.instance_name)
    grace_s = TAKEOVER_GRACE_POLLS * settings.lease_poll_s
    return Ownership(lease, settings.instance_name, settings.lease_poll_s, grace_s=grace_s)
