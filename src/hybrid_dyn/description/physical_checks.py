"""Physical checks of a robot description, run before any output exists: the URDF's structure (a tree of
links) and the physical consistency of each body's inertial parameters.

Each check returns a list of one-line problems (empty: the input is fine), so that its caller raises its
own ``HybridDynError`` subclass with its own context (a URDF path, a parameter file) and no check hides
another. Nothing here reads a file or writes one.
"""
from __future__ import annotations

import math

import numpy as np

# ------------------------------------------------------------------ URDF structure
JOINT_TYPES = ("revolute", "continuous", "prismatic", "fixed", "floating", "planar")  # the URDF specification's


def urdf_tree_problems(root) -> list[str]:
    """What keeps the URDF element tree ``root`` from being a tree of links: a link or joint without a
    name, a name used twice, a joint without ``<parent link=..>`` or ``<child link=..>`` or naming a link
    that is not there, a link that is the child of two joints, not exactly one root link, or a cycle
    (links no path from the root reaches). Every later walk of the tree (chains, subtrees) terminates
    once this list is empty."""
    problems = []
    links = [ln.get("name") for ln in root.findall("link")]
    if any(not n for n in links):
        problems.append("a <link> has no name")
    dup = sorted({n for n in links if n and links.count(n) > 1})
    if dup:
        problems.append(f"links {dup} are defined more than once")
    names = set(filter(None, links))
    parent_of, children = {}, {}
    joint_names = []
    for j in root.findall("joint"):
        name = j.get("name")
        joint_names.append(name)
        label = repr(name) if name else "without a name"
        if not name:
            problems.append("a <joint> has no name")
        if j.get("type") not in JOINT_TYPES:
            problems.append(f"joint {label} has type {j.get('type')!r}, not one of {', '.join(JOINT_TYPES)}")
        ends = {}
        for tag in ("parent", "child"):
            el = j.find(tag)
            ends[tag] = el.get("link") if el is not None else None
            if not ends[tag]:
                problems.append(f"joint {label} has no <{tag} link=...>")
            elif ends[tag] not in names:
                problems.append(f"joint {label} names {tag} link {ends[tag]!r}, which is not a <link>")
        if ends["parent"] and ends["child"]:
            if ends["child"] in parent_of:
                problems.append(f"link {ends['child']!r} is the child of two joints ({parent_of[ends['child']][0]!r} "
                                f"and {name!r})")
            else:
                parent_of[ends["child"]] = (name, ends["parent"])
                children.setdefault(ends["parent"], []).append(ends["child"])
    dup = sorted({n for n in joint_names if n and joint_names.count(n) > 1})
    if dup:
        problems.append(f"joints {dup} are defined more than once")
    if problems:
        return problems
    roots = [n for n in dict.fromkeys(links) if n not in parent_of]
    if len(roots) != 1:
        return [f"it has {len(roots)} root links {roots[:5]}, not one" + (" (a joint cycle?)" if not roots else "")]
    seen, todo = {roots[0]}, [roots[0]]
    while todo:  # every link has at most one parent here, so this visits each link once
        for c in children.get(todo.pop(), []):
            if c not in seen:
                seen.add(c)
                todo.append(c)
    cut = sorted(names - seen)
    if cut:
        return [f"links {cut[:5]} form a joint cycle (no path from the root link {roots[0]!r} reaches them)"]
    return []


# ------------------------------------------------------------ physical consistency
def inertial_problems(mass: float, inertia, triangle: bool = True) -> list[str]:
    """Why (mass [kg], inertia (xx, xy, xz, yy, yz, zz) [kg m^2] about the COM) is not a rigid body: a
    negative or non-finite mass, an inertia that is not positive definite (positive semi-definite for a
    zero mass or a point mass), or principal moments that break the triangle inequality
    (I1 + I2 >= I3 for every ordering; ``triangle=False`` skips it, for a published set kept as published).
    A relative tolerance of 1e-9 absorbs rounding of printed values."""
    out = []
    if not (math.isfinite(mass) and mass >= 0):
        out.append(f"mass {mass} kg is not a finite non-negative number")
    xx, xy, xz, yy, yz, zz = (float(v) for v in inertia)
    if not all(math.isfinite(v) for v in (xx, xy, xz, yy, yz, zz)):
        return out + ["its inertia has non-finite entries"]
    moments = np.linalg.eigvalsh(np.array([[xx, xy, xz], [xy, yy, yz], [xz, yz, zz]]))
    scale = max(float(np.abs(moments).max()), 1e-300)
    tol = 1e-9 * scale
    if moments[0] < -tol:
        out.append(f"its inertia is not positive semi-definite (principal moments {_g(moments)} kg m^2)")
    elif moments[0] <= tol and mass > 0 and moments[-1] > tol:
        out.append(f"its inertia is singular but not zero (principal moments {_g(moments)} kg m^2): no rigid body")
    elif triangle and moments[0] + moments[1] < moments[2] - tol:
        out.append(f"its principal moments {_g(moments)} kg m^2 break the triangle inequality (I1 + I2 >= I3)")
    return out


def _g(values) -> str:
    return "[" + ", ".join(f"{v:.4g}" for v in values) + "]"
