"""Reading a scenario file into a validated Scenario, with errors that name the field."""

from __future__ import annotations

from pathlib import Path
from typing import get_args

import yaml
from pydantic import BaseModel, ValidationError
from pydantic_core import ErrorDetails

from cpbc.errors import ScenarioError
from cpbc.resources import scenarios_dir
from cpbc.scenario import schema
from cpbc.scenario.schema import Scenario, SystemScenario
from cpbc.scenario.schema.kinds import KINDS


def _union_tags() -> frozenset[str]:
    """The ``type`` values of the discriminated unions: pydantic puts the tag in the error
    location (``controllers[1].cpbc.kp``), but it is no key of the scenario. Those of the
    registered kinds and of the schema's own unions (obstacles, shaping, paths, systems)."""
    tags: set[str] = {*KINDS.constraint_types, *KINDS.law_types}
    for obj in vars(schema).values():
        if isinstance(obj, type) and issubclass(obj, BaseModel) and "type" in obj.model_fields:
            tags.update(t for t in get_args(obj.model_fields["type"].annotation)
                        if isinstance(t, str))
    return frozenset(tags)


_TAGS = _union_tags()
# the specs' class names, which pydantic puts in the location of a union of a spec and a
# literal (``robot.friction.FrictionSpec.coulomb``); no key of a scenario is one
_SPECS = frozenset(name for name, obj in vars(schema).items()
                   if isinstance(obj, type) and issubclass(obj, BaseModel))


def _path(loc: tuple[object, ...]) -> str:
    out = ""
    for part in loc:
        if isinstance(part, int):
            out += f"[{part}]"
        elif isinstance(part, str) and (
            part.startswith(("function-", "tagged-union", "list[", "literal[")) or part in _TAGS
            or part in _SPECS
        ):
            continue  # pydantic's internal union branch labels
        else:
            out += f".{part}" if out else str(part)
    return out or "(top level)"


def _message(err: ErrorDetails) -> str:
    kind, msg = err["type"], err["msg"]
    if kind == "extra_forbidden":
        return (
            "unknown key; remove it or check its spelling against docs/scenario-reference.md"
        )
    if kind == "string_pattern_mismatch":
        return (f"{err.get('input')!r} is not a valid name: use letters, digits and _ . + -, "
                "starting with a letter or digit")
    if kind == "missing":
        return "required key is missing"
    if kind == "union_tag_invalid":
        expected = err.get("ctx", {}).get("expected_tags", "")
        tag = err.get("ctx", {}).get("tag", err.get("input"))
        return f"unknown type {tag!r}; registered types: {expected}"
    if kind == "too_long":
        ctx = err.get("ctx", {})
        return (f"holds {ctx.get('actual_length')} entries, more than the "
                f"{ctx.get('max_length')} allowed; shorten it")
    if kind == "union_tag_not_found":
        return "needs a 'type' key"
    return msg.removeprefix("Value error, ")


def format_validation_error(exc: ValidationError) -> ScenarioError:
    errors = exc.errors()
    first = errors[0]
    lines = [f"{_path(e['loc'])}: {_message(e)}" for e in errors[:10]]
    more = f"\n  … and {len(errors) - 10} more" if len(errors) > 10 else ""
    err = ScenarioError(_path(first["loc"]), _message(first))
    err.args = ("invalid scenario:\n  " + "\n  ".join(lines) + more,)
    return err


def resolve_scenario_path(name: str | Path) -> Path:
    """A path as given, or the name of a shipped scenario (``thesis_ch7``)."""
    p = Path(name)
    if p.is_file():
        return p
    if p.is_dir():
        inside = sorted(x.name for x in p.glob("*.y*ml"))[:8]
        hint = f" (YAML files in it: {', '.join(inside)})" if inside else ""
        raise ScenarioError("", f"{name} is a directory, not a scenario file: give the path "
                            f"of a YAML file{hint}")
    shipped = scenarios_dir() / (p.name if p.suffix else f"{p.name}.yaml")
    if shipped.is_file():
        return shipped
    available = ", ".join(sorted(s.stem for s in scenarios_dir().glob("*.yaml")))
    raise ScenarioError("", f"scenario file not found: {name} (shipped scenarios: {available})")


def read_text(file: Path) -> str:
    """The file's text, decoded as UTF-8 (a byte-order mark is allowed); at most
    MAX_FILE_BYTES of it (a larger file is refused before it is read whole)."""
    try:
        with file.open("rb") as fh:
            data = fh.read(MAX_FILE_BYTES + 1)
    except OSError as exc:
        raise ScenarioError("", f"cannot read {file}: {exc.strerror or exc}") from None
    if len(data) > MAX_FILE_BYTES:
        raise ScenarioError("", f"{file} is larger than {MAX_FILE_BYTES // 1_000_000} MB, the "
                            "limit of a scenario file; split it into several scenarios")
    try:
        return data.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        line = data[: exc.start].count(b"\n") + 1
        raise ScenarioError(
            "", f"{file} is not UTF-8 text: byte 0x{data[exc.start]:02x} on line {line} cannot "
            "be decoded; save the file as UTF-8"
        ) from None


#: A scenario file's size limit: a hundred times the largest shipped one, far more than
#: thousands of cases take; a larger file is refused before it is parsed.
MAX_FILE_BYTES = 1_000_000
#: The most nodes (values, lists, mappings) a scenario's YAML may expand to through its
#: aliases; the check counts each distinct node once, so a billion-laughs file is refused in
#: milliseconds.
MAX_VALUES = 1_000_000
_LOADER: type[yaml.SafeLoader] = getattr(yaml, "CSafeLoader", yaml.SafeLoader)


def _yaml_path(path: str, key: object) -> str:
    return f"{path}[{key}]" if isinstance(key, int) else (f"{path}.{key}" if path else str(key))


def _children(node: yaml.Node) -> list[yaml.Node]:
    if isinstance(node, yaml.MappingNode):
        return [n for pair in node.value for n in pair]
    if isinstance(node, yaml.SequenceNode):
        return list(node.value)
    return []


def _check_size(root: yaml.Node) -> None:
    """Refuse a document that refers to itself, or that expands (through its aliases,
    ``*name``, each a copy of the ``&name`` node) to more than MAX_VALUES nodes: a few lines
    of aliases nine deep stand for 10⁹ values. Each distinct node is visited once."""
    size: dict[int, int] = {}  # by node identity: an alias is the node it names
    open_: set[int] = set()  # nodes whose children are being counted: their ancestors
    stack: list[tuple[yaml.Node, bool]] = [(root, False)]
    while stack:
        node, counted = stack.pop()
        key = id(node)
        if counted:
            open_.discard(key)
            size[key] = 1 + sum(1 if isinstance(c, yaml.ScalarNode) else size[id(c)]
                                for c in _children(node))
            if size[key] > MAX_VALUES:
                line = node.start_mark.line + 1
                raise ScenarioError("", f"the YAML holds more than {MAX_VALUES:,} values (its "
                                    f"aliases expanded), from line {line}; write a scenario "
                                    "with fewer values or aliases")
        elif key in open_:
            raise ScenarioError("", f"the YAML on line {node.start_mark.line + 1} contains "
                                "itself through an alias; a scenario cannot be recursive")
        elif key not in size:
            open_.add(key)
            stack.append((node, True))
            stack.extend((c, False) for c in _children(node)
                         if not isinstance(c, yaml.ScalarNode) and id(c) not in size)


def _check_duplicate_keys(root: yaml.Node) -> None:
    """YAML lets a repeated key silently replace the first; a scenario must not. Each
    distinct node is checked once (an alias names a node already checked)."""
    checked: set[int] = set()
    stack: list[tuple[yaml.Node, str]] = [(root, "")]
    while stack:
        node, path = stack.pop()
        if id(node) in checked:
            continue
        checked.add(id(node))
        if isinstance(node, yaml.MappingNode):
            stack.extend(reversed(_check_mapping(node, path)))
        elif isinstance(node, yaml.SequenceNode):
            items = [(item, i) for i, item in enumerate(node.value)
                     if not isinstance(item, yaml.ScalarNode)]  # a scalar holds no keys
            stack.extend((item, _yaml_path(path, i)) for item, i in reversed(items))


def _check_mapping(node: yaml.MappingNode, path: str) -> list[tuple[yaml.Node, str]]:
    """Refuses a key given twice; returns the values to check, with their paths."""
    seen: dict[object, int] = {}
    values = []
    for key_node, value_node in node.value:
        key = key_node.value if isinstance(key_node, yaml.ScalarNode) else None
        if key is not None and key != "<<":
            field = _yaml_path(path, key)
            line = key_node.start_mark.line + 1
            if key in seen:
                raise ScenarioError(
                    field, f"duplicate key on line {line} (first given on line "
                    f"{seen[key]}); YAML would silently keep the second: remove one"
                )
            seen[key] = line
        values.append((value_node, _yaml_path(path, key) if key else path))
    return values


def parse_yaml(text: str, file: Path) -> object:
    """The YAML document in ``text``, refusing duplicate keys (named with their line) and
    documents that expand beyond MAX_VALUES nodes. Parsed once (with libyaml when PyYAML
    has it), checked, then built."""
    try:
        loader = _LOADER(text)
        try:
            node = loader.get_single_node()
            if node is None:
                return None
            _check_size(node)
            _check_duplicate_keys(node)
            return loader.construct_document(node)
        finally:
            loader.dispose()
    except yaml.YAMLError as exc:
        raise ScenarioError("", f"{file} is not valid YAML: {exc}") from None
    except RecursionError:
        raise ScenarioError("", f"{file} nests its lists or mappings too deeply") from None


def _mapping(path: str | Path) -> tuple[dict[str, object], Path]:
    """The scenario file's top-level mapping and its resolved path."""
    file = resolve_scenario_path(path)
    raw = parse_yaml(read_text(file), file)
    if not isinstance(raw, dict):
        raise ScenarioError("", f"{file} must hold a mapping of scenario keys at the top level")
    return raw, file


def load_scenario(path: str | Path) -> tuple[Scenario, Path]:
    """Parse and validate a YAML scenario; returns it with its resolved path."""
    raw, file = _mapping(path)
    try:
        return Scenario.model_validate(raw), file
    except ValidationError as exc:
        raise format_validation_error(exc) from None


def load_any(path: str | Path) -> tuple[Scenario | SystemScenario, Path]:
    """An arm scenario, or a Part I one when the file has a ``system:`` block."""
    raw, file = _mapping(path)
    kind: type[Scenario] | type[SystemScenario] = (
        SystemScenario if "system" in raw else Scenario)
    try:
        return kind.model_validate(raw), file
    except ValidationError as exc:
        raise format_validation_error(exc) from None
