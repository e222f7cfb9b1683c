"""The URDF text both engines read: every mesh URI made an absolute path, joints in one order,
continuous joints made unbounded revolute ones (cpbc.model.loading)."""

from __future__ import annotations

import os
import re
from collections.abc import Sequence
from pathlib import Path

from cpbc.errors import ModelError
from cpbc.model.arms import example_robot_data_share
from cpbc.model.meshes import mujoco_mesh

_MESH_URI = re.compile(r'(<mesh\b[^>]*?\bfilename\s*=\s*)(["\'])(.*?)\2', re.DOTALL)
# A <joint> element of the kinematic tree (self-closing or with children); <transmission>'s
# <joint name=…> has no type and is left alone.
_JOINT = re.compile(r"<joint\b[^>]*?/>|<joint\b[^>]*?[^/]>.*?</joint>", re.DOTALL)
_JOINT_HEAD = re.compile(r"<joint\b[^>]*>", re.DOTALL)
_CONTINUOUS = re.compile(r"""\btype\s*=\s*(["'])continuous\1""")
_REVOLUTE = re.compile(r"""\btype\s*=\s*(["'])revolute\1""")
_NAME = re.compile(r"""\bname\s*=\s*(["'])(.*?)\1""")
_LIMIT = re.compile(r"<limit\b[^>]*>", re.DOTALL)
_LOWER_UPPER = re.compile(r"""\s(lower|upper)\s*=\s*(["']).*?\2""")
_COMMENT = re.compile(r"<!--.*?-->", re.DOTALL)
_TYPED = re.compile(r"""\btype\s*=""")
_ROBOT_END = re.compile(r"</robot\s*>\s*$")


#: A folder for ``package://``: (NAME, folder) maps ``package://NAME/rest`` to
#: ``folder/rest``; (None, folder) looks it up as ``folder/NAME/rest``.
PackageDir = tuple[str | None, Path]


def package_dir(entry: str | Path) -> PackageDir:
    """One entry of ``package_dirs``: ``NAME=FOLDER`` (the folder of package NAME, whatever
    the folder is called) or a folder that holds packages."""
    name, sep, folder = str(entry).partition("=")
    if sep and name and "/" not in name:
        return name, Path(folder)
    return None, Path(entry)


def _package_dirs(urdf: Path, extra: Sequence[str | Path]) -> list[PackageDir]:
    """Folders in which ``package://NAME/...`` is looked up (after the URDF's own folders,
    see :func:`resolve_mesh_uri`): ``extra`` (folders, or ``NAME=FOLDER``), then
    ``ROS_PACKAGE_PATH``, example-robot-data and the URDF's parent folders.

    Raises:
        ModelError: one of ``extra`` is not an existing folder.
    """
    given = [package_dir(p) for p in extra]
    missing = [str(p) for p in extra if not package_dir(p)[1].is_dir()]
    if missing:
        raise ModelError(f"package_dirs {missing} do not exist or are not folders",
                         "package_dirs")
    dirs = [Path(p) for p in os.environ.get("ROS_PACKAGE_PATH", "").split(os.pathsep) if p]
    share = example_robot_data_share()
    if share is not None:
        dirs.append(share)
    dirs += list(urdf.resolve().parents)
    return list(dict.fromkeys([*given, *((None, d) for d in dirs)]))


def _looked_up(package: str, rest: str, urdf: Path,
               package_dirs: Sequence[PackageDir]) -> list[Path]:
    """Where ``package://package/rest`` may be, in order."""
    looked = [d / rest for d in urdf.resolve().parents if d.name == package]
    for name, d in package_dirs:
        if name is not None:
            looked += [d / rest] if name == package else []
            continue
        looked.append(d / package / rest)
        if d.name == package:
            looked.append(d / rest)
    return looked


def resolve_mesh_uri(uri: str, urdf: Path, package_dirs: Sequence[PackageDir]) -> Path:
    """Absolute path of a URDF mesh reference; ModelError naming the URI if it is missing.

    ``package://NAME/rest`` is first looked up from the URDF's own location (the nearest of
    its parent folders called NAME), so that a package shipped with its URDF wins over a
    namesake elsewhere, then in each of ``package_dirs`` (:data:`PackageDir`).
    """
    looked: list[Path] = []
    package = None
    if uri.startswith("package://"):
        package, _, rest = uri[len("package://"):].partition("/")
        looked = _looked_up(package, rest, urdf, package_dirs)
    elif uri.startswith("file://"):
        looked.append(Path(uri[len("file://"):]))
    else:
        p = Path(uri)
        looked.append(p if p.is_absolute() else urdf.resolve().parent / p)
    for p in looked:
        if p.is_file():
            return p.resolve()
    where = ", ".join(str(p) for p in looked[:4]) + (" …" if len(looked) > 4 else "")
    hint = (f"; if package '{package}' is a folder of another name, map it: "
            f"{package}=FOLDER in robot.package_dirs (cpbc.robot: --package-dir "
            f"{package}=FOLDER)" if package else "")
    raise ModelError(f"mesh '{uri}' referenced by {urdf} not found (looked in {where}){hint}")


def resolve_urdf_meshes(
    urdf: Path, text: str | None = None, package_dirs: Sequence[str | Path] = ()
) -> str:
    """The URDF text, without its comments, with every mesh filename replaced by an absolute
    path."""
    text = _COMMENT.sub("", urdf.read_text() if text is None else text)
    dirs = _package_dirs(urdf, package_dirs)

    def sub(m: re.Match[str]) -> str:
        path = mujoco_mesh(resolve_mesh_uri(m.group(3), urdf, dirs))
        return f"{m.group(1)}{m.group(2)}{path}{m.group(2)}"

    return _MESH_URI.sub(sub, text)


def sort_joints(text: str) -> str:
    """The URDF text with the joints of its kinematic tree in name order, after the links.

    Pinocchio (through urdfdom) visits the children of a link in the order of their joints'
    names, MuJoCo's URDF parser in the order of the file; in name order both number the joints
    of a branching robot (two arms, four legs) alike. Comments must be gone (see
    :func:`resolve_urdf_meshes`): a commented-out joint would be moved out of its comment.
    """
    blocks = [m for m in _JOINT.finditer(text)
              if (head := _JOINT_HEAD.match(m.group(0))) and _TYPED.search(head.group(0))]

    def name(m: re.Match[str]) -> str:
        head = _JOINT_HEAD.match(m.group(0))
        found = _NAME.search(head.group(0)) if head else None
        return found.group(2) if found else ""

    end = _ROBOT_END.search(text)
    if not blocks or end is None:
        return text
    parts, last = [], 0
    for m in blocks:
        parts.append(text[last:m.start()])
        last = m.end()
    parts.append(text[last:end.start()])
    joints = "\n".join(m.group(0) for m in sorted(blocks, key=name))
    return "".join(parts) + joints + "\n" + text[end.start():]


def unbound_continuous_joints(text: str) -> tuple[str, tuple[str, ...]]:
    """The URDF text with every ``continuous`` joint made ``revolute`` without position
    limits, and the names of those joints.

    Pinocchio models a continuous joint by (cos q, sin q) (nq = 2, nv = 1), MuJoCo by the
    angle (nq = nv = 1); as an unbounded revolute joint both use the angle, so q means the
    same in both engines and the controllers' x = q holds. The ``<limit>`` keeps its effort
    and velocity; its lower/upper (meaningless for a continuous joint) are dropped, and the
    loader marks the joint unbounded in both engines.

    A continuous or revolute joint without ``<limit>`` (TIAGo dual's casters) gets one
    without effort or rate limit (urdfdom, hence Pinocchio, refuses a revolute joint without);
    a revolute one is then read as what it describes, a continuous joint.
    """
    names: list[str] = []

    def sub(m: re.Match[str]) -> str:
        block = m.group(0)
        head = _JOINT_HEAD.match(block)
        if head is None:
            return block
        no_limit = block.endswith("</joint>") and not _LIMIT.search(block)
        if not (_CONTINUOUS.search(head.group(0))
                or (no_limit and _REVOLUTE.search(head.group(0)))):
            return block
        name = _NAME.search(head.group(0))
        names.append(name.group(2) if name else "?")
        block = _CONTINUOUS.sub('type="revolute"', block, count=1)
        if no_limit:  # urdfdom requires one for a revolute joint
            return block[:-len("</joint>")] + '<limit effort="0" velocity="0"/></joint>'
        return _LIMIT.sub(lambda lim: _LOWER_UPPER.sub("", lim.group(0)), block)

    return _JOINT.sub(sub, text), tuple(names)
