"""URDF parsing: the serial chain from a base link to a tool link, and its limits.

A URDF is refused with `RobotModelError` naming the problem: XML that does not
parse, a root that is not <robot>, more than `MAX_URDF_JOINTS` joints, a cycle, a
link with two parents, an unknown base or tip link, a chain without movable joint
or with an unsupported joint type, a position limit missing or reversed. The tool
link defaults to the end of the only moving subtree (`default_tip`), the base link
to the URDF's root (docs/robots.md).
"""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from dataclasses import dataclass

import numpy as np

from ft_core.errors import SuiteError

_MOVABLE = {"revolute", "continuous", "prismatic"}
_SUPPORTED = _MOVABLE | {"fixed"}


class RobotModelError(SuiteError):
    """A robot model could not be built; the message names the problem."""


@dataclass(frozen=True)
class _UrdfJoint:
    name: str
    kind: str
    parent: str
    child: str

#: Largest URDF accepted (bytes): real arms' URDFs are tens of kilobytes.
MAX_URDF_BYTES = 10_000_000
#: Most joints a URDF may declare (the tree walks are quadratic in them at worst).
MAX_URDF_JOINTS = 2000

def _parse_tree(xml: str) -> tuple[ET.Element, dict[str, _UrdfJoint], set[str]]:
    """Parse URDF XML into (root element, joints by child link, link names)."""
    try:
        root = ET.fromstring(xml)
    except ET.ParseError as exc:
        raise RobotModelError(f"URDF does not parse: {exc}") from exc
    if root.tag != "robot":
        raise RobotModelError(f"URDF root element is <{root.tag}>, expected <robot>")
    links = {link.get("name", "") for link in root.findall("link")}
    by_child: dict[str, _UrdfJoint] = {}
    elements = root.findall("joint")
    if len(elements) > MAX_URDF_JOINTS:
        raise RobotModelError(f"URDF declares {len(elements)} joints (at most "
                              f"{MAX_URDF_JOINTS})")
    for element in elements:
        parent, child = element.find("parent"), element.find("child")
        if parent is None or child is None:
            raise RobotModelError(f"URDF joint {element.get('name')!r} lacks <parent> or <child>")
        joint = _UrdfJoint(element.get("name", ""), element.get("type", ""),
                           parent.get("link", ""), child.get("link", ""))
        if joint.child in by_child:
            raise RobotModelError(f"URDF link {joint.child!r} has two parent joints")
        by_child[joint.child] = joint
    if not links:
        raise RobotModelError("URDF has no links")
    _check_acyclic(by_child)
    return root, by_child, links


def _check_acyclic(by_child: dict[str, _UrdfJoint]) -> None:
    """Raise RobotModelError if the joints form a cycle (the tree walks would not end).

    Each link has one parent at most, so a cycle is a walk up the parents that comes
    back to a link of the same walk. Every link is walked once: linear in the joints.
    """
    done: set[str] = set()
    for start in by_child:
        walk: list[str] = []
        seen: set[str] = set()
        link = start
        while link in by_child and link not in done:
            if link in seen:
                cycle = walk[walk.index(link):]
                raise RobotModelError(f"URDF joints form a cycle through links "
                                      f"{[name[:64] for name in cycle[:6]]}"
                                      f"{' ...' if len(cycle) > 6 else ''}")
            seen.add(link)
            walk.append(link)
            link = by_child[link].parent
        done.update(walk)


def _children(by_child: dict[str, _UrdfJoint]) -> dict[str, list[_UrdfJoint]]:
    """Joints below each link."""
    children: dict[str, list[_UrdfJoint]] = {}
    for joint in by_child.values():
        children.setdefault(joint.parent, []).append(joint)
    return children


def _below(link: str, children: dict[str, list[_UrdfJoint]]) -> list[_UrdfJoint]:
    """Every joint of the subtree below `link`, without recursion (a URDF may be deep)."""
    found, stack = [], list(children.get(link, []))
    while stack:
        joint = stack.pop()
        found.append(joint)
        stack.extend(children.get(joint.child, []))
    return found


def _moving_subtrees(link: str, children: dict[str, list[_UrdfJoint]]) -> list[_UrdfJoint]:
    """The joints below `link` whose subtree holds at least one movable joint."""
    return [j for j in children.get(link, []) if j.kind in _MOVABLE
            or any(k.kind in _MOVABLE for k in _below(j.child, children))]


def _leaves(link: str, children: dict[str, list[_UrdfJoint]]) -> list[str]:
    """The links without children below `link` (candidate tool links)."""
    leaves = [j.child for j in _below(link, children) if j.child not in children]
    return leaves or [link]


def _is_gripper(joint: _UrdfJoint) -> bool:
    """A movable joint named as a gripper's or a finger's (Unitree Z1's `jointGripper`)."""
    return joint.kind in _MOVABLE and any(word in joint.name.lower()
                                          for word in ("gripper", "finger"))


def _default_tip(base: str, by_child: dict[str, _UrdfJoint]) -> str:
    """Walk down from `base` along the only subtree that moves; return where that ends.

    Branches with fixed joints only (sensor frames, UR's `base` frame) are passed
    by; past the last movable joint a lone chain of fixed joints (the tool frame) is
    followed to its end. A lone movable joint named like a gripper's or a finger's
    after the arm (Unitree Z1's `jointGripper`) ends the arm: it is not a joint of
    the task (give `tip_link` to include it). A two-finger gripper makes the tree
    branch into moving subtrees at the hand, so the default tip of a Panda with
    fingers is `panda_hand`, the link that carries them.
    Raises RobotModelError, naming the branch and candidate tips, when the tree
    branches into moving subtrees before any movable joint (a mobile base, two arms).
    """
    children = _children(by_child)
    tip, moved = base, False
    while True:
        moving = _moving_subtrees(tip, children)
        below = children.get(tip, [])
        if len(moving) == 1 and not (moved and _is_gripper(moving[0])):
            step = moving[0]
        elif not moving and len(below) == 1:  # a fixed tool frame past the last joint
            step = below[0]
        else:
            break
        moved = moved or step.kind in _MOVABLE
        tip = step.child
    if len(moving) > 1 and not moved:
        candidates = sorted({leaf for j in moving for leaf in _leaves(j.child, children)})
        raise RobotModelError(
            f"the URDF tree branches at {tip!r} into {len(moving)} moving subtrees "
            f"({', '.join(j.child for j in moving)}) before any movable joint: set tip_link "
            f"(and base_link if needed) to choose the arm; candidate tip links: "
            f"{candidates[:12]}{' ...' if len(candidates) > 12 else ''}")
    return tip


def _chain(base: str, tip: str, by_child: dict[str, _UrdfJoint]) -> list[_UrdfJoint]:
    """Joints on the path from `base` down to `tip`, base first (fixed ones included)."""
    path, link = [], tip
    while link != base:
        if link not in by_child:
            raise RobotModelError(f"tip_link {tip!r} is not below base_link {base!r} in the URDF")
        joint = by_child[link]
        path.append(joint)
        link = joint.parent
    return path[::-1]


def _limits(root: ET.Element, names: list[str]) -> tuple[np.ndarray, ...]:
    """Position (lower, upper), velocity and effort limits of the named joints, from <limit>.

    Continuous joints have infinite position limits; a missing (or zero) velocity or
    effort limit is infinite (no limit).
    """
    elements = {j.get("name"): j for j in root.findall("joint")}
    lower, upper, velocity, effort = [], [], [], []
    for name in names:
        joint = elements[name]
        limit = joint.find("limit")
        if joint.get("type") == "continuous":
            lo, hi = -math.inf, math.inf
        elif limit is None or limit.get("lower") is None or limit.get("upper") is None:
            raise RobotModelError(f"URDF joint {name!r} has no position <limit>")
        else:
            lo, hi = float(limit.get("lower", "")), float(limit.get("upper", ""))
        vel = float(limit.get("velocity", "0") or 0.0) if limit is not None else 0.0
        force = float(limit.get("effort", "0") or 0.0) if limit is not None else 0.0
        if not lo <= hi:
            raise RobotModelError(f"URDF joint {name!r} has lower limit {lo} above upper {hi}")
        lower.append(lo)
        upper.append(hi)
        velocity.append(vel if vel > 0 else math.inf)
        effort.append(force if force > 0 else math.inf)
    return np.array(lower), np.array(upper), np.array(velocity), np.array(effort)


def _as_revolute(root: ET.Element, names: list[str]) -> str:
    """Rewrite the named continuous joints as revolute ones, so that q has one entry each.

    Joints off the chain named like a link are renamed (see below).

    Pinocchio models a continuous joint by (cos, sin); the suite works with angles.
    The wide placeholder limits written here are never used: `_limits` reports them
    as infinite.
    """
    links = {link.get("name", "") for link in root.findall("link")}
    for joint in root.findall("joint"):
        if joint.get("name") in links and joint.get("name") not in names:
            # A joint named like a link (Unitree Z1) makes Pinocchio's frame lookups by
            # name ambiguous; joints off the chain are never referred to by name.
            joint.set("name", f"{joint.get('name')}__joint")
        if joint.get("name") in names and joint.get("type") == "continuous":
            joint.set("type", "revolute")
            limit = joint.find("limit")
            if limit is None:
                limit = ET.SubElement(joint, "limit", effort="0", velocity="0")
            limit.set("lower", "-1e9")
            limit.set("upper", "1e9")
    return ET.tostring(root, encoding="unicode")


@dataclass(frozen=True)
class UrdfChain:
    """The serial chain of a URDF from `base_link` to `tip_link`.

    Attributes:
        name: the URDF robot name.
        joint_names: movable joints from base to tip.
        lower, upper: position limits (rad or m; +-inf for continuous joints).
        velocity_limits: |qd| limits (rad/s or m/s; inf where the URDF gives none).
        effort_limits: |effort| limits (N m or N; inf where the URDF gives none).
        base_link, tip_link: the chain's end links.
        urdf: the URDF, the chain's continuous joints rewritten as revolute ones and
            joints off the chain named like a link renamed (`_as_revolute`).
    """

    name: str
    joint_names: tuple[str, ...]
    lower: np.ndarray
    upper: np.ndarray
    velocity_limits: np.ndarray
    effort_limits: np.ndarray
    base_link: str
    tip_link: str
    urdf: str


def read_chain(xml: str, base_link: str | None = None, tip_link: str | None = None) -> UrdfChain:
    """Parse URDF XML and find the chain from `base_link` (default: the root link) to `tip_link`.

    The default tip is `_default_tip`'s. Raises RobotModelError naming the problem.
    """
    root, by_child, links = _parse_tree(xml)
    roots = sorted(links - set(by_child))
    if len(roots) != 1:
        raise RobotModelError(f"URDF must have exactly one root link, found {roots}")
    base = base_link or roots[0]
    for role, link in (("base_link", base), ("tip_link", tip_link)):
        if link is not None and link not in links:
            raise RobotModelError(f"{role} {link!r} is not a link of the URDF")
    tip = tip_link or _default_tip(base, by_child)
    chain = _chain(base, tip, by_child)
    for joint in chain:
        if joint.kind not in _SUPPORTED:
            raise RobotModelError(
                f"joint {joint.name!r} of type {joint.kind!r} on the chain is not supported"
            )
    names = [j.name for j in chain if j.kind in _MOVABLE]
    if not names:
        raise RobotModelError(f"the chain from {base!r} to {tip!r} has no movable joint")
    lower, upper, velocity, effort = _limits(root, names)
    return UrdfChain(root.get("name", "robot"), tuple(names), lower, upper, velocity, effort,
                     base, tip,
                     _as_revolute(root, names))
