"""What usdcrowd may write: never a user's input, never a file it did not make, one run per folder.

A command run from the command line opens a :func:`session` naming its
inputs and outputs. Within it:

- nothing is written onto an input file, nor onto a layer, value clip or
  image an input USD stage uses;
- an output folder is *claimed*: an advisory lock (``.usdcrowd/lock``,
  ``flock``, released by the OS on any exit, even a kill) keeps a second
  run out at once (and out of folders inside it, or holding it); a folder
  holding entries usdcrowd did not write is refused unless the session
  has ``force``, and a folder made for one kind of output (a shot, a
  render...) is refused for another;
- each top-level entry usdcrowd writes in an output folder is recorded in
  ``.usdcrowd/written`` (one JSON line per write: a folder's name, or a
  file's name, size, mtime, content digest and the command that wrote it).
  A file whose size and mtime match none of the versions usdcrowd wrote,
  nor its content any of theirs (a copy, ``cp -r``, has new mtimes), was
  changed by someone else and is theirs now; a folder usdcrowd made is usdcrowd's
  with everything in it. Only usdcrowd's entries are ever replaced or
  removed, ``force`` or not (``force`` replaces only a file the user named).

Outside a session (the library API, tests) nothing is checked; a file
rewritten in a folder that keeps a record is recorded again, so the next
command does not take it for a user's edit. Worker processes (a local pool,
Ray) find the session in the environment variable ``USDCROWD_SESSION``.
"""

from __future__ import annotations

import contextlib
import errno
import json
import os
import re
from dataclasses import dataclass, field
from pathlib import Path

from .core.errors import UsdcrowdError

# Files up to this size are also known by a digest of their content (read once more as they are written).
DIGEST_MAX_BYTES = 64 << 20

# The temporary names usdcrowd writes under before a rename: ".<stem>.partial-<8 hex><suffix>".
PARTIAL_NAME = re.compile(r"^\..+\.partial-[0-9a-f]{8}(\.[^/]*)?$")
STATE_DIR = ".usdcrowd"
RECORD = "written"
LOCK = "lock"
ENV = "USDCROWD_SESSION"
# Layers followed from one input stage when listing what it uses (sublayers, references, payloads, clips).
MAX_INPUT_LAYERS = 2000


@dataclass
class Session:
    """The inputs of one command run, the output folders it claimed, and whether ``--force`` was given."""

    inputs: dict = field(default_factory=dict)       # (st_dev, st_ino) -> the path the user knows it by
    roots: list = field(default_factory=list)        # claimed output folders, absolute
    force: bool = False
    command: str | None = None                       # the command, recorded with what it writes
    named: set = field(default_factory=set)          # the output paths the user named (what --force may replace)
    named_inputs: set = field(default_factory=set)   # the input paths the user named (never replaced in place)
    locks: dict = field(default_factory=dict)        # root -> open lock file (this process's)
    in_place: set = field(default_factory=set)       # layers of an input this run may replace (edit_in_place)
    made_state: set = field(default_factory=set)     # folders whose state folder this run created
    _records: dict = field(default_factory=dict)     # root -> (bytes read, {name: entry})

    # -------------------------------------------------------------- inputs
    def input_named(self, path) -> str | None:
        """The input ``path`` is (as the user named it), or None."""
        try:
            st = os.stat(path)
        except OSError:
            return None
        return self.inputs.get((st.st_dev, st.st_ino))

    # -------------------------------------------------------------- records
    def root_of(self, path: Path) -> Path | None:
        """The innermost claimed output folder holding ``path``."""
        best = None
        for root in self.roots:
            if path != root and root in path.parents and (best is None or best in root.parents):
                best = root
        return best

    def entries(self, root: Path) -> dict:
        """``{name: entry}`` of what usdcrowd wrote at the top of ``root`` (the record, read incrementally)."""
        done, table = self._records.get(root, (0, {}))
        try:
            with open(root / STATE_DIR / RECORD, "rb") as fh:
                fh.seek(done)
                tail = fh.read()
        except OSError:
            return table
        end = tail.rfind(b"\n") + 1                 # a line another process is still appending waits
        for line in tail[:end].splitlines():
            with contextlib.suppress(ValueError, TypeError, KeyError):
                _merge(table, json.loads(line))
        self._records[root] = (done + end, table)
        return table

    def owns(self, root: Path, name: str) -> bool:
        """Whether the entry ``name`` at the top of ``root`` is usdcrowd's (written by it, and unchanged since)."""
        entry = self.entries(root).get(name)
        if entry is None:                   # an empty folder holds nothing of anyone's (a run stopped early)
            return (root / name).is_dir() and not (root / name).is_symlink() and not any(os.scandir(root / name))
        try:
            st = os.lstat(root / name)
        except FileNotFoundError:
            return True
        if entry["kind"] == "dir":
            return os.path.isdir(root / name) and not os.path.islink(root / name)
        # Any version usdcrowd wrote: the one a kill left just before its rename, or one a rollback put back;
        # or the same bytes with a new mtime (a copied folder).
        if entry["kind"] != "file":
            return False
        if (st.st_size, st.st_mtime_ns) in entry["states"]:
            return True
        return (bool(entry["digests"]) and any(st.st_size == size for size, _ in entry["states"])
                and _digest(root / name, st.st_size) in entry["digests"])

    def record(self, root: Path, name: str) -> None:
        """Note that usdcrowd wrote (or made) the entry ``name`` at the top of ``root``."""
        path = root / name
        try:
            st = os.lstat(path)
        except OSError:
            return
        if os.path.isdir(path):
            self.record_dir(root, name)     # once: frames land in it by thousands
        else:
            self.record_file(root, name, st)

    def record_file(self, root: Path, name: str, st: os.stat_result, content: Path | None = None) -> None:
        """Note the file ``name`` at the top of ``root`` with the size and mtime of ``st`` and the digest of
        ``content`` (the file itself unless given: the temporary file about to be renamed onto it), once per
        version."""
        now = self.entries(root).get(name, {})
        if now.get("kind") == "file" and (now["size"], now["mtime_ns"]) == (st.st_size, st.st_mtime_ns):
            return
        self._append(root, {"kind": "file", "name": name, "size": st.st_size, "mtime_ns": st.st_mtime_ns,
                            "digest": _digest(content or root / name, st.st_size), "by": self.command})

    def record_dir(self, root: Path, name: str) -> None:
        """Note that usdcrowd makes the folder ``name`` at the top of ``root`` (before making it)."""
        if self.entries(root).get(name, {}).get("kind") != "dir":
            self._append(root, {"kind": "dir", "name": name})

    def record_folder(self, root: Path, what: str) -> None:
        """Note what kind of output folder ``root`` is (its entry ``"."``)."""
        self._append(root, {"kind": "folder", "name": ".", "what": what})

    def _append(self, root: Path, entry: dict) -> None:
        (root / STATE_DIR).mkdir(exist_ok=True)
        line = (json.dumps(entry) + "\n").encode()
        # 0o666 less the umask, as any file: a shared group folder stays writable by the group.
        fd = os.open(root / STATE_DIR / RECORD, os.O_WRONLY | os.O_APPEND | os.O_CREAT, 0o666)
        try:
            os.write(fd, line)      # one short O_APPEND write: whole, even beside other processes
        finally:
            os.close(fd)
        _merge(self.entries(root), entry)


def _merge(table: dict, entry: dict) -> None:
    """Add a record line to ``{name: entry}``; a file's entry keeps every (size, mtime_ns) usdcrowd gave it,
    and every digest."""
    name = entry["name"]
    if entry["kind"] == "file":
        before = table.get(name, {})
        if before.get("kind") != "file":
            before = {}
        entry["states"] = before.get("states", set()) | {(entry["size"], entry["mtime_ns"])}
        entry["digests"] = before.get("digests", set()) | ({entry["digest"]} if entry.get("digest") else set())
    table[name] = entry


def _digest(path, size: int) -> str | None:
    """A hex digest of the file's content, or None for one larger than :data:`DIGEST_MAX_BYTES` (a crowd
    layer of gigabytes is known by its size and mtime alone) or one that cannot be read."""
    import hashlib

    if size > DIGEST_MAX_BYTES:
        return None
    try:
        with open(path, "rb") as fh:
            return hashlib.file_digest(fh, "blake2b").hexdigest()[:32]
    except OSError:
        return None


_SESSION: Session | None = None


def current() -> Session | None:
    """The session of this command run (also in its worker processes), or None in library use."""
    global _SESSION
    if _SESSION is None and os.environ.get(ENV):
        data = json.loads(os.environ[ENV])
        _SESSION = Session(force=data["force"], roots=[Path(r) for r in data["roots"]], command=data["command"],
                           named={Path(p) for p in data["named"]})
        for path in data["inputs"]:
            _add_input(_SESSION, path, path)
    return _SESSION


def _publish(s: Session) -> None:
    """Hand the session to worker processes started from now on."""
    names = sorted(set(s.inputs.values()))
    os.environ[ENV] = json.dumps({"force": s.force, "roots": [os.fspath(r) for r in s.roots], "command": s.command,
                                  "named": sorted(os.fspath(p) for p in s.named),
                                  "inputs": [os.path.abspath(p) for p in names]})


def ray_runtime_env() -> dict | None:
    """Ray's ``runtime_env`` that gives a cluster's workers this run's session (None outside one)."""
    return {"env_vars": {ENV: os.environ[ENV]}} if os.environ.get(ENV) else None


def _add_input(s: Session, path, shown) -> bool:
    try:
        st = os.stat(path)
    except OSError:
        return False
    s.inputs.setdefault((st.st_dev, st.st_ino), os.fspath(shown))
    return True


def _assets_of(layer, folder: str) -> list[str]:
    """Files a layer names besides its composition: asset-valued attributes (textures, behavior maps) in
    text layers, and value clips (crowd.clips/) on root prims."""
    from pxr import Sdf

    found = []

    def add(asset) -> None:
        path = getattr(asset, "path", asset)
        if isinstance(path, str) and path:
            found.append(os.path.normpath(os.path.join(folder, path)))

    for prim in layer.rootPrims:
        for clip_set in (prim.GetInfo("clips") if prim.HasInfo("clips") else {}).values():
            for asset in list(clip_set.get("assetPaths", [])) + [clip_set.get("manifestAssetPath")]:
                if asset is not None:
                    add(asset)
    if layer.GetFileFormat().formatId != "usda":
        return found                        # binary crowd layers hold animation, not textures

    def visit(path) -> None:
        if not path.IsPropertyPath():
            return
        spec = layer.GetPropertyAtPath(path)
        if isinstance(spec, Sdf.AttributeSpec) and spec.typeName == Sdf.ValueTypeNames.Asset:
            if spec.HasDefaultValue():
                add(spec.default)

    layer.Traverse(Sdf.Path.absoluteRootPath, visit)
    return found


def files_used(path: str) -> list[str]:
    """The files a USD stage is made of, besides itself: its layers' sublayers, references, payloads,
    value clips and asset-valued attributes (images), nearest first."""
    import stat

    from pxr import Sdf

    found, todo = [], [os.path.abspath(path)]
    seen = set(todo)
    while todo and len(seen) < MAX_INPUT_LAYERS:
        current_path = todo.pop()
        try:
            if not stat.S_ISREG(os.stat(current_path).st_mode):
                continue                    # a FIFO would block; the reader refuses it with its own error
            layer = Sdf.Layer.FindOrOpen(current_path)
        except Exception:                   # unreadable: the command's own reader reports it
            layer = None
        if layer is None:
            continue
        folder = os.path.dirname(current_path)
        for asset in layer.GetCompositionAssetDependencies():
            dep = os.path.normpath(os.path.join(folder, asset))
            if dep not in seen and os.path.isfile(dep):
                seen.add(dep)
                found.append(dep)
                todo.append(dep)
        for dep in _assets_of(layer, folder):
            if dep not in seen and os.path.isfile(dep):
                seen.add(dep)
                found.append(dep)
                if dep.endswith((".usd", ".usda", ".usdc")):
                    todo.append(dep)
        del layer
    return found


@contextlib.contextmanager
def session(inputs=(), force: bool = False, outputs=(), command: str | None = None):
    """Guard every write of the command run inside: see the module's docstring.

    Parameters
    ----------
    inputs : iterable of str
        The files the command reads, as the user named them. USD stages
        among them bring the layers they use.
    force : bool
        Write into output folders that hold entries usdcrowd did not write
        (those entries are still never replaced), and replace a single
        output file the user named (in ``outputs``) even if usdcrowd did not write it.
    outputs : iterable of str
        The output paths the user named.
    command : str, optional
        The command's name, recorded with each file it writes.
    """
    global _SESSION
    previous, env = _SESSION, os.environ.get(ENV)
    s = Session(force=force, command=command, named={Path(os.path.abspath(p)) for p in outputs})
    for path in inputs:
        if path is None or not _add_input(s, path, path):
            continue
        s.named_inputs.add(Path(os.path.realpath(path)))
        if os.path.splitext(os.fspath(path))[1].lower() in (".usd", ".usda", ".usdc"):
            for dep in files_used(os.fspath(path)):
                _add_input(s, dep, dep)
    _SESSION = s
    _publish(s)
    try:
        yield s
    finally:
        for root, fh in s.locks.items():
            _forget_if_empty(root, root in s.made_state)
            fh.close()
        _SESSION = previous
        if env is None:
            os.environ.pop(ENV, None)
        else:
            os.environ[ENV] = env


def _forget_if_empty(root: Path, made: bool) -> None:
    """A run that wrote nothing (refused, failed early) leaves its folder as it found it: no state folder."""
    import shutil

    with contextlib.suppress(OSError):
        if (made and not (root / STATE_DIR / RECORD).exists()) or all(e.name == STATE_DIR for e in os.scandir(root)):
            shutil.rmtree(root / STATE_DIR, ignore_errors=True)


# ------------------------------------------------------------------ checks
def check_not_input(path, what: str = "output") -> None:
    """Refuse an output that would land on one of the session's inputs."""
    s = current()
    if s is None:
        return
    name = s.input_named(path)
    if name is not None:
        same = "" if os.path.abspath(name) == os.path.abspath(path) else f" (it is {name})"
        raise UsdcrowdError(f"the {what} would overwrite an input of this command{same}: choose another "
                            f"{'folder' if what == 'output folder' else 'name'}", file=os.fspath(path))


def _top(s: Session, path: Path) -> tuple[Path, str]:
    """The folder whose record decides about ``path``, and ``path``'s top-level name in it."""
    root = s.root_of(path)
    if root is None:
        return path.parent, path.name
    return root, path.relative_to(root).parts[0]


def check_write(final) -> None:
    """Refuse to write ``final`` when it is an input, or replaces an entry usdcrowd did not write.

    Raises
    ------
    UsdcrowdError
        One line naming the file.
    """
    s = current()
    if s is None:
        return
    final = Path(os.path.abspath(final))
    check_not_input(final)
    if final in s.in_place:
        return
    root, name = _top(s, final)
    entry = root / name
    if _partial(name) or not os.path.lexists(entry):
        return
    if s.owns(root, name):
        if root not in s.roots:
            _refuse_another_commands(s, root, name, final)
        return
    if s.force and root not in s.roots and final in s.named:
        return                              # a single output file the user named, replaced on --force
    if entry == final:
        raise UsdcrowdError("exists and was not written by usdcrowd (or was changed since): usdcrowd replaces "
                            "only its own files; move it away or choose another output"
                            + ("" if root in s.roots else ", or give --force to replace it"), file=os.fspath(final))
    raise UsdcrowdError(f"{name} in {root} was not made by usdcrowd: usdcrowd writes only in its own folders; "
                        f"move it away or choose another output folder", file=os.fspath(final))


def _refuse_another_commands(s: Session, root: Path, name: str, final: Path) -> None:
    """A single file written into another command's output folder may not replace what that command wrote
    there (``new -o shot/shot.usda`` would replace a shot's entry layer)."""
    kind = s.entries(root).get(".", {}).get("what")
    by = s.entries(root)[name].get("by")
    if kind and by and by != s.command:
        raise UsdcrowdError(f"is part of the {kind} that usdcrowd {by} wrote in this folder: choose another name",
                            file=os.fspath(final))


def will_write(tmp, final) -> None:
    """Record ``final`` with ``tmp``'s size and mtime just before ``tmp`` is renamed onto it (a rename keeps
    both): a run killed between the two leaves a file the record still knows as usdcrowd's."""
    s = current()
    if s is None:
        return
    final = Path(os.path.abspath(final))
    root, name = _top(s, final)
    if _partial(name) or root / name != final:
        return                              # inside a folder of usdcrowd's: the folder's entry covers it
    s.record_file(root, name, os.stat(tmp), Path(tmp))


def wrote(final) -> None:
    """Record that ``final`` was written (call after the rename)."""
    s = current()
    final = Path(os.path.abspath(final))
    if s is None:
        _keep_record_true(final)
        return
    root, name = _top(s, final)
    if _partial(name):
        return
    if root in s.roots or root / name == final:
        s.record(root, name)
    inner = _innermost_record(final, stop=root)
    if inner is not None:                   # a folder of its own inside this run's (the demo's shot)
        Session(command=s.command).record(inner, final.relative_to(inner).parts[0])


def _keep_record_true(final: Path) -> None:
    """Library use (no session) checks nothing, but a file it rewrites in an output folder that keeps a
    record is recorded again: else usdcrowd's own next command would take it for the user's edit."""
    root = _innermost_record(final)
    if root is not None:
        name = final.relative_to(root).parts[0]
        if not _partial(name):
            Session().record(root, name)


def _innermost_record(final: Path, stop: Path | None = None) -> Path | None:
    """The nearest folder above ``final`` (at most 4 up, below ``stop``) that keeps a record."""
    for folder in list(final.parents)[:4]:
        if folder == stop:
            return None
        if (folder / STATE_DIR / RECORD).is_file():
            return folder
    return None


def make_dir(path) -> Path:
    """``path`` made (with its parents) as usdcrowd's own folder, or refused like :func:`check_write`."""
    path = Path(path)
    s = current()
    if s is None:
        path.mkdir(parents=True, exist_ok=True)
        return path
    full = Path(os.path.abspath(path))
    root = s.root_of(full)
    if root is None:                        # a new or claimed output folder itself: claim() checks it
        path.mkdir(parents=True, exist_ok=True)
        return path
    name = full.relative_to(root).parts[0]
    if os.path.lexists(root / name):
        check_write(full)
    elif not _partial(name):
        # Recorded before it is made: a worker process that finds it a moment later finds it usdcrowd's.
        s.record_dir(root, name)
    path.mkdir(parents=True, exist_ok=True)
    return path


def edit_in_place(path) -> None:
    """Let this run replace ``path``, a layer of its own input (the cameras.usda of the shot that
    ``cameras`` or ``frame`` films): its folder is locked for the run, and ``path`` is refused
    when usdcrowd wrote it and someone changed it since (unless ``force``). A shot's camera layer
    with no record (made by the library API, or by an older usdcrowd) is the shot's to replace."""
    s = current()
    if s is None:
        return
    full = Path(os.path.abspath(path))
    if Path(os.path.realpath(full)) in s.named_inputs:
        raise UsdcrowdError("is named as an input of this command and would be replaced: copy it elsewhere first",
                            file=os.fspath(full))
    if full.parent not in s.locks:
        check_free(full.parent)
        _lock(s, full.parent)
    if full.name in s.entries(full.parent) and not s.owns(full.parent, full.name) and not s.force:
        raise UsdcrowdError("changed since usdcrowd wrote it: your edits would be lost; move them to shot.usda "
                            "(the layer for edits) or give --force to replace it", file=os.fspath(full))
    with contextlib.suppress(OSError):
        st = os.stat(full)
        s.inputs.pop((st.st_dev, st.st_ino), None)
    s.in_place.add(full)


def merge_into(path) -> None:
    """Let this run update ``path``, a layer of the user's that usdcrowd keeps up to date but never
    replaces (a shot's shot.usda: only its metadata and sublayers are usdcrowd's, every opinion in it is
    kept), even when someone edited it since usdcrowd wrote it."""
    s = current()
    if s is not None:
        check_not_input(Path(os.path.abspath(path)))
        s.in_place.add(Path(os.path.abspath(path)))


def check_remove(path) -> None:
    """Refuse to remove what usdcrowd did not write (inside a session)."""
    check_write(path)


# ------------------------------------------------------------------ output folders
def claim(folder, what: str | None = None) -> Path:
    """Make ``folder`` an output folder of the running command: checked, locked for this run, recorded.

    ``what`` names the kind of folder (``"shot"``, ``"render"``, ``"dataset"``...):
    a folder made for one kind is refused for another (a dataset written
    into a render's folder would replace its manifest).

    Raises
    ------
    UsdcrowdError
        It is an input, another run holds it, or it holds entries usdcrowd
        did not write (without ``force``).
    """
    s = current()
    folder = Path(folder)
    if s is None:
        return folder
    full = Path(os.path.abspath(folder))
    if full in s.locks:
        return folder
    check_not_input(full, "output folder")
    if s.root_of(full) is None:
        check_free(full)
        _lock(s, full)
    # else: inside a folder this run holds already (a dataset's sequences, the demo's shot): its lock covers it.
    if full not in s.roots:
        # Folders nested in this run's own are claimed one after another (a worker's sequences):
        # forget the earlier ones, so the session stays small however many there are.
        s.roots = [r for r in s.roots if s.root_of(r) is None or r in full.parents] + [full]
        _publish(s)
    if what is not None and not (full / STATE_DIR / RECORD).is_file() and _older_output(full, what):
        if not s.force:
            raise UsdcrowdError(f"holds a {what} made before usdcrowd kept a record of its files: give --force to "
                                "adopt it (its files then count as usdcrowd's) or choose another folder",
                                file=os.fspath(folder))
        import fnmatch

        for entry in os.scandir(full):          # adopted: the names usdcrowd gives a folder of this kind
            if any(fnmatch.fnmatch(entry.name, pattern) for pattern in ADOPTABLE[what]):
                s.record(full, entry.name)
    foreign = [e.name for e in sorted(os.scandir(full), key=lambda e: e.name)
               if e.name != STATE_DIR and not _partial(e.name) and not s.owns(full, e.name)
               and not (full / e.name / STATE_DIR / RECORD).is_file()]     # an output folder of its own
    # A layer this run merges into (merge_into: the user's edits kept) is theirs to have edited.
    foreign = [n for n in foreign if full / n not in s.in_place]
    changed = [n for n in foreign if n in s.entries(full)]
    if changed and not s.force:
        raise UsdcrowdError(f"{', '.join(changed[:3])}{' and more' if len(changed) > 3 else ''} changed since usdcrowd "
                            "wrote it: edits are never replaced; move it away or choose another output folder",
                            file=os.fspath(folder))
    if foreign and not s.force:
        shown = ", ".join(n + ("/" if os.path.isdir(full / n) else "") for n in foreign[:3])
        more = f" and {len(foreign) - 3} more" if len(foreign) > 3 else ""
        raise UsdcrowdError(f"the output folder holds what usdcrowd did not write ({shown}{more}): give an empty "
                            "or new folder, or --force to write beside them (they are never replaced)",
                            file=os.fspath(folder))
    if what is not None:
        made = s.entries(full).get(".", {}).get("what")
        if made is not None and made != what:
            raise UsdcrowdError(f"this folder holds a {made}'s outputs, not a {what}'s: choose another folder",
                                file=os.fspath(folder))
        if made is None:
            s.record_folder(full, what)
    return folder


# What a folder of each kind held when an earlier usdcrowd wrote it (adopted with --force).
ADOPTABLE = {
    "shot": ("shot.usda", "crowd.usdc", "crowd.part*.usdc", "crowd.clips", "cameras.usda", "trajectories.png"),
    "render": ("manifest.json", "exr", "png", "json", "mot", "coco.json", "contact_sheet.png", "render.mp4"),
    "dataset": ("manifest.json", "spec.toml", "sequences", "mot", "coco", "README.md", "card.png"),
}


def _older_output(folder: Path, what: str) -> bool:
    """Whether ``folder`` holds a ``what`` an earlier usdcrowd wrote (its own signature: a render's or a
    dataset's manifest, a shot's customLayerData), from before folders kept a record."""
    if what in ("render", "dataset"):
        try:
            doc = json.loads((folder / "manifest.json").read_text())
        except (OSError, ValueError):
            return False
        return isinstance(doc, dict) and ({"header", "frames"} <= doc.keys() if what == "render"
                                          else "spec_sha256" in doc)
    if what == "shot" and (folder / "shot.usda").is_file():
        from pxr import Sdf

        with contextlib.suppress(Exception):
            layer = Sdf.Layer.FindOrOpen(os.fspath(folder / "shot.usda"))
            return isinstance(layer.customLayerData.get("usdcrowd"), dict)
    return False


def check_free(folder) -> None:
    """Refuse a folder inside an output folder another run is writing (``simulate -o ds/sequences/x/shot``
    while the dataset ``ds`` is made), before anything is made in it."""
    s = current()
    if s is None:
        return
    full = Path(os.path.abspath(folder))
    if s.root_of(full) is not None:
        return                              # inside this run's own folder
    for parent in full.parents:
        if parent not in s.roots and parent not in s.locks and _busy(parent):
            raise UsdcrowdError(f"is inside {parent}, which another usdcrowd run is writing: wait for it "
                                "to finish or choose another folder", file=os.fspath(full))
    # And the other way round: a run writing in a folder inside this one (a render into shot/render).
    with contextlib.suppress(OSError):
        for entry in os.scandir(full):
            inner = Path(entry.path)
            if entry.is_dir(follow_symlinks=False) and inner not in s.locks and _busy(inner):
                raise UsdcrowdError(f"another usdcrowd run is writing in {inner}, inside this folder: wait for it "
                                    "to finish or choose another folder", file=os.fspath(full))


def _busy(folder: Path) -> bool:
    """Whether another process holds ``folder``'s lock now."""
    import fcntl

    lock = folder / STATE_DIR / LOCK
    if not lock.is_file():
        return False
    try:
        with open(lock) as fh:
            try:
                fcntl.flock(fh, fcntl.LOCK_SH | fcntl.LOCK_NB)
            except OSError as exc:
                return exc.errno in (errno.EAGAIN, errno.EACCES, errno.EWOULDBLOCK)
            fcntl.flock(fh, fcntl.LOCK_UN)
    except OSError:
        return False
    return False


def _partial(name: str) -> bool:
    """Whether ``name`` is a temporary name :func:`usdcrowd.atomic.atomic_path` makes (always usdcrowd's)."""
    return bool(PARTIAL_NAME.match(name))


def _lock(s: Session, root: Path) -> None:
    import fcntl

    if not (root / STATE_DIR).exists():
        s.made_state.add(root)
    (root / STATE_DIR).mkdir(exist_ok=True)
    fh = open(root / STATE_DIR / LOCK, "a+")
    try:
        fcntl.flock(fh, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except OSError as exc:
        fh.seek(0)
        holder = fh.read().strip()
        fh.close()
        if exc.errno in (errno.ENOLCK, errno.EOPNOTSUPP, errno.ENOSYS):
            return                          # a file system without locks (some NFS, FUSE): the run goes on unguarded
        if exc.errno not in (errno.EAGAIN, errno.EACCES, errno.EWOULDBLOCK):
            raise
        raise UsdcrowdError(f"another usdcrowd run{f' (pid {holder})' if holder else ''} is writing in this folder: "
                            "wait for it to finish or choose another folder", file=os.fspath(root)) from None
    fh.seek(0)
    fh.truncate()
    fh.write(f"{os.getpid()}\n")
    fh.flush()
    s.locks[root] = fh
