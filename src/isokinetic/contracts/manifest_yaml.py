"""Reading a manifest's YAML safely (split from :mod:`isokinetic.contracts.manifest`, which re-exports every
name here): :func:`read_manifest_bytes` refuses a manifest that is too large, not a regular file or a symlink out
of its folder; :func:`check_yaml_events` walks the parser's events and refuses anchors, aliases, merge keys,
duplicate keys, tags, complex keys, deep nesting and too many values before any object is built;
:func:`parse_yaml` then loads it. Problems raise :class:`ManifestError` naming file and key."""

from __future__ import annotations

from pathlib import Path

import yaml

#: A manifest is a page of YAML; anything larger is refused unread (bytes).
MAX_MANIFEST_BYTES = 1_000_000
#: Deepest nesting of mappings/sequences (the spec needs 5: top, cases, case, columns, channel).
MAX_DEPTH = 32
#: Most YAML values (scalars and collections) in one manifest (1000 cases use about 20 000).
MAX_NODES = 200_000
#: YAML tags a manifest may carry explicitly (the plain types of the YAML core schema).
SAFE_TAGS = frozenset("tag:yaml.org,2002:" + t for t in
                      ("null", "bool", "int", "float", "str", "seq", "map", "timestamp"))


class ManifestError(ValueError):
    """A broken manifest: the whole campaign is rejected. The message names file and key."""

    def __init__(self, path: str, key: str | None, problem: str):
        self.path, self.key, self.problem = path, key, problem
        super().__init__(f"{path}: key {key!r}: {problem}" if key else f"{path}: {problem}")


def _at(mark) -> str:
    return f" at line {mark.line + 1}, column {mark.column + 1}" if mark is not None else ""


def _short_tag(tag: str) -> str:
    return "!!" + tag[len("tag:yaml.org,2002:"):] if tag.startswith("tag:yaml.org,2002:") else tag


def check_yaml_events(data: bytes, where: str) -> None:
    """Refuse hostile YAML from the parser's event stream, before any object is built.

    Raises :class:`ManifestError` naming the key path (``cases[2].file``, ``columns.force``; None at
    the top level) for: an anchor or alias, a merge key ``<<``, a duplicate mapping key, a tag other
    than :data:`SAFE_TAGS`, a non-scalar mapping key, nesting deeper than :data:`MAX_DEPTH`, more
    than :data:`MAX_NODES` values. Syntax errors are left to the caller (raised as yaml.YAMLError).
    Aliases are never expanded here, so the walk costs one pass over at most 1 MB of text.
    """
    loader = getattr(yaml, "CSafeLoader", yaml.SafeLoader)
    stack: list[dict] = []   # open collections: kind, path, expect_key, key, index, keys
    nodes = 0

    def path_of_next() -> str | None:
        if not stack:
            return None
        top = stack[-1]
        if top["kind"] == "seq":
            return f"{top['path'] or ''}[{top['index']}]"
        if top["expect_key"]:
            return top["path"] or None
        return f"{top['path']}.{top['key']}" if top["path"] else top["key"]

    def refuse(key, problem, event):
        raise ManifestError(where, key, f"invalid YAML{_at(event.start_mark)}: {problem}")

    def done_value():
        if stack:
            top = stack[-1]
            if top["kind"] == "seq":
                top["index"] += 1
            else:
                top["expect_key"] = True

    for event in yaml.parse(data, Loader=loader):
        if isinstance(event, (yaml.StreamStartEvent, yaml.StreamEndEvent, yaml.DocumentStartEvent,
                              yaml.DocumentEndEvent)):
            continue
        if isinstance(event, (yaml.SequenceEndEvent, yaml.MappingEndEvent)):
            stack.pop()
            done_value()
            continue
        key = path_of_next()
        as_key = bool(stack) and stack[-1]["kind"] == "map" and stack[-1]["expect_key"]
        if isinstance(event, yaml.AliasEvent):
            refuse(key, f"alias *{event.anchor} is not allowed (anchors and aliases are refused: "
                        "they can expand to gigabytes)", event)
        nodes += 1
        if nodes > MAX_NODES:
            refuse(key, f"more than {MAX_NODES} values", event)
        if event.anchor is not None:
            refuse(key, f"anchor &{event.anchor} is not allowed (anchors and aliases are refused: "
                        "they can expand to gigabytes)", event)
        if event.tag not in (None, "!") and event.tag not in SAFE_TAGS:
            refuse(key, f"tag {_short_tag(event.tag)!r} is not allowed (only plain values: "
                        "no tag constructs objects)", event)
        if as_key:
            top = stack[-1]
            if not isinstance(event, yaml.ScalarEvent):
                refuse(key, "mapping keys must be plain values, got a "
                            + ("sequence" if isinstance(event, yaml.SequenceStartEvent) else "mapping"), event)
            name = event.value
            full = f"{top['path']}.{name}" if top["path"] else name
            if name == "<<" and event.implicit[0]:
                refuse(full, "merge keys '<<' are not allowed", event)
            if name in top["keys"]:
                refuse(full, "duplicate key (YAML would silently keep the last value)", event)
            top["keys"].add(name)
            top["key"], top["expect_key"] = name, False
            continue
        if isinstance(event, yaml.ScalarEvent):
            done_value()
        else:
            if len(stack) >= MAX_DEPTH:
                refuse(key, f"nested deeper than {MAX_DEPTH} levels", event)
            stack.append({"kind": "seq" if isinstance(event, yaml.SequenceStartEvent) else "map",
                          "path": key or "", "expect_key": True, "key": None, "index": 0, "keys": set()})


def parse_yaml(data: bytes, where: str):
    """:func:`check_yaml_events`, then yaml.safe_load; syntax errors become a ManifestError giving
    line and column."""
    try:
        check_yaml_events(data, where)
        return yaml.load(data, Loader=getattr(yaml, "CSafeLoader", yaml.SafeLoader))
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None) or getattr(exc, "context_mark", None)
        problem = getattr(exc, "problem", None) or str(exc)
        raise ManifestError(where, None, f"invalid YAML{_at(mark)}: {problem}") from None
    except (ValueError, OverflowError, RecursionError) as exc:   # e.g. an integer of 5000 digits
        if isinstance(exc, ManifestError):
            raise
        raise ManifestError(where, None, f"invalid YAML: {exc}") from None


def read_manifest_bytes(path: str | Path) -> bytes:
    """The manifest's bytes, refused unread when it is not a regular file, is a symlink leading out
    of its folder, or holds more than :data:`MAX_MANIFEST_BYTES`."""
    where, p = str(path), Path(path)
    if p.is_symlink() and not _inside(p, p.absolute().parent):
        raise ManifestError(where, None, f"is a symlink to {p.resolve().as_posix()}, outside the campaign folder")
    if not p.is_file():
        raise ManifestError(where, None, "not found" if not p.exists() else "not a regular file")
    size = p.stat().st_size
    if size > MAX_MANIFEST_BYTES:
        raise ManifestError(where, None, f"{size} bytes, more than the {MAX_MANIFEST_BYTES} bytes "
                                         "a manifest may have")
    with open(p, "rb") as fh:
        data = fh.read(MAX_MANIFEST_BYTES + 1)
    if len(data) > MAX_MANIFEST_BYTES:   # grew after the stat
        raise ManifestError(where, None, f"more than the {MAX_MANIFEST_BYTES} bytes a manifest may have")
    return data


def _inside(path: Path, folder: Path) -> bool:
    """True when ``path`` (symlinks followed) lies inside ``folder`` (symlinks followed)."""
    try:
        path.resolve().relative_to(folder.resolve())
    except ValueError:
        return False
    return True
