"""Reading YAML and JSON safely.

Every YAML file gearsim reads (config files, ``--configfile``, ``--params``, standard parameters)
goes through :func:`load_yaml`: a file larger than :data:`MAX_YAML_BYTES`, not UTF-8 text, or
whose aliases would expand to more than :data:`MAX_YAML_NODES` nodes (a "billion laughs" bomb)
is refused in one line before anything is expanded; no message prints a value of the file.
"""

from __future__ import annotations

import json
import re
from pathlib import Path
from typing import Any

import yaml

from gearsim.errors import ParameterError

#: Largest YAML/JSON file read (bytes). The default configuration is about 4 kB.
MAX_YAML_BYTES = 1_000_000
#: Largest number of nodes a document may have once its aliases are expanded.
MAX_YAML_NODES = 200_000


class _Loader(getattr(yaml, "CSafeLoader", yaml.SafeLoader)):
    """SafeLoader that also reads YAML 1.2 / JSON floats without a dot (``1e-12``) as numbers
    (PyYAML's YAML 1.1 resolver would read them as strings). LibYAML's parser where PyYAML has
    it (~10 x faster: every job reads the configuration), the same nodes and the same values."""


_Loader.add_implicit_resolver(
    "tag:yaml.org,2002:float",
    re.compile(
        r"""^(?:[-+]?(?:[0-9][0-9_]*)\.[0-9_]*(?:[eE][-+]?[0-9]+)?
        |[-+]?(?:[0-9][0-9_]*)(?:[eE][-+]?[0-9]+)
        |\.[0-9_]+(?:[eE][-+][0-9]+)?
        |[-+]?\.(?:inf|Inf|INF)
        |\.(?:nan|NaN|NAN))$""",
        re.X,
    ),
    list("-+0123456789."),
)


def _expanded_size(root: yaml.Node, path: Path) -> int:
    """Nodes of the document with every alias expanded, without expanding it (memoised over the
    shared node graph); refuses recursive aliases and stops as soon as the limit is passed."""
    memo: dict[int, int] = {}
    active: set[int] = set()

    def size(node: yaml.Node) -> int:
        key = id(node)
        if key in memo:
            return memo[key]
        if key in active:
            raise ParameterError(f"{path}: recursive YAML alias (refused)")
        active.add(key)
        total = 1
        if isinstance(node, yaml.SequenceNode):
            for child in node.value:
                total += size(child)
                if total > MAX_YAML_NODES:
                    break
        elif isinstance(node, yaml.MappingNode):
            for k, v in node.value:
                total += size(k) + size(v)
                if total > MAX_YAML_NODES:
                    break
        active.discard(key)
        memo[key] = total
        if total > MAX_YAML_NODES:
            raise ParameterError(
                f"{path}: YAML expands to more than {MAX_YAML_NODES} nodes "
                "(alias bomb or oversized document; refused)"
            )
        return total

    return size(root)


def load_yaml(path: str | Path) -> Any:
    """Parse a YAML (or JSON) file with size and alias limits; ParameterError on any problem."""
    path = Path(path)
    if path.is_dir():
        raise ParameterError(f"{path}: is a directory, not a file")
    if not path.is_file():
        raise ParameterError(f"file not found: {path}")
    try:
        size = path.stat().st_size
        if size > MAX_YAML_BYTES:
            raise ParameterError(
                f"{path}: {size} bytes is larger than the limit of {MAX_YAML_BYTES} bytes"
            )
        raw = path.read_bytes()
    except OSError as exc:
        raise ParameterError(f"{path}: cannot read ({exc.strerror or exc})") from None
    if b"\x00" in raw:
        raise ParameterError(f"{path}: binary file, expected YAML or JSON text")
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError:
        raise ParameterError(f"{path}: not UTF-8 text, expected YAML or JSON") from None
    if path.suffix.lower() == ".json":
        try:
            return json.loads(text)
        except (json.JSONDecodeError, RecursionError) as exc:
            raise ParameterError(f"{path}: not valid JSON ({exc})") from None
    loader = _Loader(text)
    try:
        node = loader.get_single_node()
        if node is None:
            return None
        _expanded_size(node, path)
        return loader.construct_document(node)
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        where = f" at line {mark.line + 1}" if mark is not None else ""
        problem = getattr(exc, "problem", None) or "syntax error"
        raise ParameterError(f"{path}: not valid YAML ({problem}{where})") from None
    except RecursionError:
        raise ParameterError(f"{path}: YAML nested too deeply (refused)") from None
    finally:
        loader.dispose()


def load_mapping(path: str | Path, what: str = "file") -> dict:
    """:func:`load_yaml` for files that must hold a mapping (an empty file is ``{}``)."""
    doc = load_yaml(path)
    if doc is None:
        return {}
    if not isinstance(doc, dict):
        raise ParameterError(
            f"{path}: a {what} must be a mapping of keys, got a {type(doc).__name__}"
        )
    return doc
