"""A run directory: opened for reading, locked for training, checked for damage.

Every CLI opens a run through ``open_run``: the directory, ``config.yaml`` and
``league.db`` are checked before anything else happens, and any problem becomes one
``RunDirError`` whose message names the file, what is wrong and what the user can do.

A checkpoint directory carries a manifest (size and SHA-256 of every file, written
before the directory is renamed into place), so a resume can tell a complete checkpoint
from a deleted, truncated or garbled one without loading it, and fall back to the
newest intact one.

Only one process trains a run at a time: ``lock_run`` takes an exclusive ``flock`` on
``RUN_DIR/run.lock`` (the ``filelock`` library) and writes the holder's pid into it. The
kernel drops the lock when the holder exits, however it exits, so a killed run never
leaves a stale lock. Readers (``status``, ``evaluate``, ``report``, ``export``) take no
lock: SQLite's WAL mode lets them read while training writes.

``run_state`` tells the three states of a run apart: *training* (a live process holds the
lock), *finished* (its final evaluation written: ``evaluation.md`` is the last file a run
writes) and *stopped* (neither: stopped, killed or crashed, to be resumed).
"""

from __future__ import annotations

import errno
import fcntl
import hashlib
import json
import os
import shutil
from pathlib import Path
from typing import Callable

from filelock import FileLock, Timeout

from league.config import RUN_CONFIG_FILE, ConfigError, RunConfig, added_at_its_default, changed_keys, config_hash, saved_run_config
from league.state.store import DB_NAME, DamagedStoreError, LeagueStore

LOCK_FILE = "run.lock"
EVALUATION_FILE = "evaluation.md"  # the run's final evaluation, the last file it writes (``league.training.lifecycle.finish``)
TRAINING, STOPPED, FINISHED = "training", "stopped", "finished"  # ``run_state``
MANIFEST_FILE = "league_manifest.json"
CONFIG_META = "config"  # the validated config as created, in the store's meta table
CONFIG_HASH_META = "config_hash"
CHECKPOINTS_KEPT = 2


class RunDirError(ValueError):
    """A run directory that cannot be used as asked; the message is one line for the user."""


def check_run_dir(run_dir: Path) -> None:
    if not run_dir.exists():
        raise RunDirError(f"no run directory at {run_dir}")
    if not run_dir.is_dir():
        raise RunDirError(f"{run_dir} is a file, not a run directory")
    if not (run_dir / DB_NAME).exists():
        raise RunDirError(f"{run_dir} is not a league run directory (no {DB_NAME})")


def open_store(run_dir: Path) -> LeagueStore:
    """The run's league database, checked; a damaged one is a ``RunDirError``."""
    check_run_dir(run_dir)
    try:
        return LeagueStore(run_dir)
    except DamagedStoreError as err:
        raise RunDirError(
            f"{err}: `python -m league.run --resume {run_dir}` restores it from the copy kept with its newest "
            "checkpoint, or start a new run"
        ) from err


def unrecorded_players(run_dir: Path, store: LeagueStore) -> list[str]:
    """Folders of ``players/`` that no player of ``store`` is saved in: weights saved after the
    database's last commit that it does not know (a best response of ``league.exploit``, a snapshot)."""
    players = store.players()
    known = {p.name for p in players} | {Path(p.checkpoint).name for p in players if p.checkpoint}
    saved = (d.name for d in (Path(run_dir) / "players").glob("*") if d.is_dir() and not d.name.endswith(".partial"))
    return sorted(name for name in saved if name not in known)


def restore_damaged_database(run_dir: Path) -> str | None:
    """Replace a damaged ``league.db`` by the newest intact copy kept in a checkpoint directory
    (``Coordinator`` writes one with every checkpoint it commits). Returns the lines saying so and
    what the copy lacks (everything recorded after its checkpoint, the saved players it does not
    know named), or None when the database was intact (or no intact copy exists: ``open_store``
    then says what is wrong)."""
    path = Path(run_dir) / DB_NAME
    try:
        LeagueStore(run_dir).close()
        return None
    except DamagedStoreError as err:
        damage = err
    skipped = []  # newer copies, damaged too
    for backup in sorted(Path(run_dir).glob(f"checkpoints/iter_*/{DB_NAME}"), reverse=True):
        try:
            LeagueStore(backup.parent).close()
        except (DamagedStoreError, OSError):
            skipped.append(str(backup.relative_to(run_dir)))
            continue
        for stale in (path.with_name(DB_NAME + "-wal"), path.with_name(DB_NAME + "-shm")):
            stale.unlink(missing_ok=True)
        partial = path.with_name(DB_NAME + ".restoring")
        shutil.copyfile(backup, partial)
        os.replace(partial, path)
        restored = LeagueStore(run_dir)
        try:
            checkpoint, unknown = restored.last_checkpoint(), unrecorded_players(run_dir, restored)
        finally:
            restored.close()
        iteration = checkpoint[0] if checkpoint else 0
        newer = f" (the newer {', '.join(skipped)} {'is' if len(skipped) == 1 else 'are'} damaged too)" if skipped else ""
        lines = [
            f"{damage}; restored it from {backup.relative_to(run_dir)}, the copy kept with that checkpoint{newer}",
            f"warning: everything recorded after the checkpoint of iteration {iteration} is lost from league.db: "
            "this resume redoes the run's own training and evaluations, not the evaluations (league.evaluate) "
            "and best responses (league.exploit) recorded since: run them again",
        ]
        if unknown:
            lines.append(
                f"warning: {len(unknown)} saved player(s) the restored league.db does not know, saved after that "
                f"checkpoint: {', '.join('players/' + name for name in unknown)} (snapshots are saved again as "
                "training redoes them; a best response stays unused until league.exploit records a new one there)"
            )
        return "\n".join(lines)
    return None


def read_config(run_dir: Path) -> RunConfig:
    check_run_dir(run_dir)
    try:
        return saved_run_config(run_dir)
    except ConfigError as err:
        raise RunDirError(f"{err}; restore the config the run was started with") from err


def open_run(run_dir: Path) -> tuple[RunConfig, LeagueStore]:
    """The run's config and league database, both checked."""
    run = read_config(run_dir)
    return run, open_store(run_dir)


def record_config(store: LeagueStore, run: RunConfig) -> None:
    """Remember the config a run was created with (call inside a transaction)."""
    store.set_meta(CONFIG_META, run.model_dump(mode="json"))
    store.set_meta(CONFIG_HASH_META, config_hash(run))


def check_config_unchanged(run_dir: Path, run: RunConfig, store: LeagueStore) -> None:
    """Refuse a resume whose ``config.yaml`` differs from the one the run was created with
    (a key that a later version added, at its default, is no change)."""
    recorded = store.get_meta(CONFIG_HASH_META)
    if recorded is None or recorded == config_hash(run):  # runs made before the hash was kept are not checked
        return
    old, new = store.get_meta(CONFIG_META) or {}, run.model_dump(mode="json")
    differing = changed_keys(old, new)
    keys = [key for key in differing if not added_at_its_default(old, new, key)]
    if differing and not keys:
        return
    raise RunDirError(
        f"{run_dir / RUN_CONFIG_FILE} was changed after the run started ({', '.join(keys) or 'formatting of values'}): "
        "undo the change to resume, or start a new run with the new config"
    )


def lock_holder(run_dir: Path) -> int | None:
    """The pid written by the process holding (or last holding) the run's lock."""
    try:
        return int((run_dir / LOCK_FILE).read_text().strip())
    except (OSError, ValueError):
        return None


def _write_pid(fd: int) -> None:
    os.ftruncate(fd, 0)
    os.pwrite(fd, f"{os.getpid()}\n".encode(), 0)


def lock_run(run_dir: Path) -> FileLock:
    """Hold the run directory's exclusive lock until the process exits (or ``release()``)."""
    lock = FileLock(run_dir / LOCK_FILE, timeout=0, on_acquired=_write_pid)
    try:
        lock.acquire()
    except Timeout:
        holder = lock_holder(run_dir)
        who = f"process {holder}" if holder else "another process"
        raise RunDirError(
            f"{run_dir} is in use by {who} (it holds {LOCK_FILE}): wait for that run to finish or stop it; "
            "league.status, evaluate and report can read the run meanwhile"
        ) from None
    return lock


def lock_is_held(run_dir: Path) -> bool:
    """Whether a live process holds the run's lock, found by asking for a shared ``flock`` without
    waiting and letting it go at once; nothing is written (the file is opened read-only). A
    ``league.run`` that tries to take the lock in those microseconds is refused as if the run
    were in use."""
    try:
        fd = os.open(run_dir / LOCK_FILE, os.O_RDONLY)
    except OSError:  # no lock file: nothing ever trained here
        return False
    try:
        fcntl.flock(fd, fcntl.LOCK_SH | fcntl.LOCK_NB)
    except BlockingIOError:
        return True
    finally:
        os.close(fd)  # closing drops the shared lock, if it was granted
    return False


def run_state(run_dir: Path) -> str:
    """``TRAINING`` while a live process holds the lock (training, evaluating or starting), else
    ``FINISHED`` once the final evaluation is written, else ``STOPPED`` (interrupted, killed or
    crashed; ``league.run --resume`` goes on)."""
    if lock_is_held(run_dir):
        return TRAINING
    return FINISHED if (run_dir / EVALUATION_FILE).exists() else STOPPED


def checkpoint_directory(run_dir: Path, iteration: int) -> Path:
    return Path(run_dir) / "checkpoints" / f"iter_{iteration:06d}"


def write_checkpoint(run_dir: Path, iteration: int, save: Callable[[Path], None]) -> Path:
    """``save(directory)`` into a temporary directory, its manifest written, then renamed into
    place as ``iteration``'s checkpoint; a failure (a full disk, a stop signal) removes the
    temporary directory."""
    final = checkpoint_directory(run_dir, iteration)
    partial = final.with_name(final.name + ".partial")
    for stale in (partial, final):
        if stale.exists():
            shutil.rmtree(stale)
    try:
        save(partial)
        write_manifest(partial)
    except BaseException:
        shutil.rmtree(partial, ignore_errors=True)
        raise
    partial.rename(final)
    return final


def prune_checkpoints(run_dir: Path, store: LeagueStore, kept: int = CHECKPOINTS_KEPT) -> None:
    """Remove every checkpoint directory but the newest ``kept`` the store records (partial ones too)."""
    keep = {run_dir / path for _, path in store.checkpoints()[-kept:]}
    for directory in (run_dir / "checkpoints").glob("iter_*"):
        if directory not in keep:
            shutil.rmtree(directory, ignore_errors=True)


def fresh_directory(path: Path) -> Path:
    """``path``, with whatever was there removed (a module saved anew, or one left by a killed run)."""
    if path.exists():
        shutil.rmtree(path)
    return path


def write_replacing(path: Path, text: str) -> None:
    """Write ``text`` to ``path`` in one rename: a reader sees the old file or the new one, never a part."""
    partial = path.with_name(path.name + ".partial")
    partial.write_text(text)
    partial.replace(path)


def _digest(path: Path) -> str:
    with path.open("rb") as f:
        return hashlib.file_digest(f, "sha256").hexdigest()


def write_manifest(checkpoint_dir: Path) -> None:
    """Record size and digest of every file of a freshly written checkpoint."""
    files = sorted(p for p in checkpoint_dir.rglob("*") if p.is_file())
    manifest = {str(p.relative_to(checkpoint_dir)): [p.stat().st_size, _digest(p)] for p in files}
    (checkpoint_dir / MANIFEST_FILE).write_text(json.dumps(manifest, indent=0))


def checkpoint_problem(checkpoint_dir: Path) -> str | None:
    """Why a checkpoint directory cannot be resumed from, or ``None`` if it is intact."""
    if not checkpoint_dir.is_dir():
        return "missing"
    manifest_path = checkpoint_dir / MANIFEST_FILE
    if not manifest_path.exists():  # written before manifests were kept: trust a complete-looking one
        return None if (checkpoint_dir / "rllib_checkpoint.json").is_file() else "incomplete (no rllib_checkpoint.json)"
    try:
        manifest = json.loads(manifest_path.read_text())
    except (OSError, ValueError):
        return f"damaged ({MANIFEST_FILE} unreadable)"
    for name, (size, digest) in manifest.items():
        path = checkpoint_dir / name
        try:
            if path.stat().st_size != size or _digest(path) != digest:
                return f"damaged ({name} differs from what was written)"
        except OSError:  # deleted, perhaps just now by a run pruning its old checkpoints
            return f"damaged ({name} missing)"
    return None


def usable_checkpoints(run_dir: Path, store: LeagueStore) -> tuple[list[tuple[int, str]], list[str]]:
    """Recorded checkpoints that are intact on disk, newest first, and what is wrong with
    the newer ones that are not (pruned checkpoints older than the newest intact one are not listed)."""
    usable, problems = [], []
    for iteration, path in reversed(store.checkpoints()):
        problem = checkpoint_problem(run_dir / path)
        if problem is None:
            usable.append((iteration, path))
        elif not usable:
            problems.append(f"the checkpoint of iteration {iteration} ({path}) is {problem}")
    return usable, problems


def directory_size(path: Path) -> int:
    return sum(p.stat().st_size for p in path.rglob("*") if p.is_file())


def is_disk_full(err: BaseException) -> bool:
    """``OSError`` ENOSPC from a file write, or SQLite's own report of a full disk."""
    if isinstance(err, OSError) and err.errno in (errno.ENOSPC, errno.EDQUOT):
        return True
    return "database or disk is full" in str(err)


def disk_full_message(run_dir: Path, store: LeagueStore | None) -> str:
    """What to tell the user when a write into the run directory ran out of space
    (``store`` is ``None`` for a new run, whose directory was removed)."""
    where = run_dir if run_dir.exists() else run_dir.parent
    free = f"{shutil.disk_usage(where).free / 2**20:.1f} MiB free"
    usable = usable_checkpoints(run_dir, store)[0] if store is not None else []
    if not usable:
        return f"disk full while creating {run_dir} ({free}); nothing was kept: free space and start again"
    need = directory_size(run_dir / usable[0][1])
    return (
        f"disk full while writing into {run_dir}: {free}, a checkpoint needs about {need / 2**20:.1f} MiB; "
        f"the last checkpoint (iteration {usable[0][0]}) is intact: free space, then resume with "
        f"`python -m league.run --resume {run_dir}`"
    )


def run_differences(first: Path, second: Path) -> list[str]:
    """Where two run directories differ, one line each (empty: the same run): every table of
    their ``league.db`` but the wall-clock columns (``LeagueStore.contents``), and the weights
    of every saved player, bit for bit."""
    import pickle

    import numpy as np

    differences = []
    stores = [LeagueStore(Path(first)), LeagueStore(Path(second))]
    try:
        contents = [store.contents() for store in stores]
    finally:
        for store in stores:
            store.close()
    for table in sorted(set(contents[0]) | set(contents[1])):
        rows = [contents[0].get(table, []), contents[1].get(table, [])]
        if rows[0] != rows[1]:
            extra = [row for row in rows[0] if row not in rows[1]] + [row for row in rows[1] if row not in rows[0]]
            differences.append(f"{table}: {len(rows[0])} and {len(rows[1])} rows, first differing: {extra[:1]}")
    players = [{p.parent.name for p in Path(run).glob("players/*/module_state.pkl")} for run in (first, second)]
    if players[0] != players[1]:
        differences.append(f"saved players: {sorted(players[0] ^ players[1])} in one run only")
    for name in sorted(players[0] & players[1]):
        states = []
        for run in (first, second):
            with open(Path(run) / "players" / name / "module_state.pkl", "rb") as file:
                states.append(pickle.load(file))
        different = [k for k in states[0] if k not in states[1] or not np.array_equal(states[0][k], states[1][k])]
        if different or set(states[1]) - set(states[0]):
            differences.append(f"player {name}: weights differ ({', '.join(different) or 'tensor names'})")
    return differences
