"""Chains of scissor-like elements (SLEs, Peng et al. 2019, Sec. 2): the `structure.scissors` shorthand, expanded
into bodies, pins, sliders and probes when a scene is resolved.

A chain of n SLEs lies in the plane of its deployment `direction` d and `height_axis` h (unit, perpendicular);
its pins turn about the chord k = d x h of every bar. With bars of length L at the angle theta to d, w = L cos
theta and H = L sin theta, SLE i = 1..n is
  bar <name>_up<i>:   root b_i = origin + (i - 1) w d,       span axis  cos(theta) d + sin(theta) h
  bar <name>_down<i>: root a_i = origin + (i - 1) w d + H h, span axis  cos(theta) d - sin(theta) h
both with chord_axis k. The points carry the names of Peng et al. 2019, Sec. 5: upper ends a_1..a_{n+1}, lower
ends b_1..b_{n+1}, mid-length pivots c_1..c_n. Pins (axis chord): <name>_c<i> joins the two bars of SLE i at
mid-length; <name>_a<i+1> the tip of up<i> to the root of down<i+1>; <name>_b<i+1> the tip of down<i> to the
root of up<i+1>. The four ends (start_lower b_1, start_upper a_1, end_upper a_{n+1}, end_lower b_{n+1}) are
free, pinned to the ground (joint <name>_<point>_pin), or kept on a line through their start across the chain
(along h) or along it (along d) (slider <name>_<point>_slider). Every named point is a probe <name>_<point>.
Deploying means theta decreasing: the chain lengthens along d and flattens along h.
"""
from __future__ import annotations

import math

import numpy as np

from .choices import fidelity, fidelity_names
from .errors import SceneError
from .schema import item_label
from .vectors import unit

ENDS = (("start_lower", "b", 0), ("start_upper", "a", 0), ("end_upper", "a", -1), ("end_lower", "b", -1))
"""(key, point letter, which SLE) of a chain's four ends."""


def bar_elements(structure: dict, chain: dict) -> int:
    """Elements per bar: the chain's elements_per_bar, else 2 for rigid and prescribed bars.

    For deformable ones structure.elements_per_body rounded up to even (the mid-length pivot must be a node).

    Args:
        structure: the resolved `structure` table.
        chain: one of its resolved scissor chains.
    """
    if chain["elements_per_bar"] is not None:
        return chain["elements_per_bar"]
    if not fidelity(structure["fidelity"]).deformable:
        return 2
    return 2 * math.ceil(structure["elements_per_body"] / 2)


def chain_tables(structure: dict, chain: dict) -> tuple[list[dict], list[dict], list[dict]]:
    """(bodies, joints, probes) of the resolved chain table, as raw scene tables.

    Args:
        structure: the resolved `structure` table.
        chain: one of its resolved scissor chains.
    """
    name, n, L = chain["name"], chain["count"], chain["bar_length"]
    d, h = unit(chain["direction"]), unit(chain["height_axis"])
    k = np.cross(d, h)
    theta = math.radians(chain["initial_angle_deg"])
    w, H = L * math.cos(theta), L * math.sin(theta)
    origin = np.asarray(chain["origin"], float)
    vector = lambda v: [float(x) for x in v]
    elements = bar_elements(structure, chain)
    bodies = []
    for i in range(1, n + 1):
        start = origin + (i - 1) * w * d
        for bar, root, span in (("up", start, math.cos(theta) * d + math.sin(theta) * h),
                                ("down", start + H * h, math.cos(theta) * d - math.sin(theta) * h)):
            bodies.append({"name": f"{name}_{bar}{i}", "length": L, "root": vector(root), "span_axis": vector(span),
                           "chord_axis": vector(k), "damping": chain["damping"], "elements": elements,
                           "section": dict(chain["section"])})
    pin = lambda joint, body, span, other, other_span: {
        "type": "pin", "name": f"{name}_{joint}", "body": body, "span": span, "other": other,
        "other_span": other_span, "axis": "chord"}
    joints = [pin(f"c{i}", f"{name}_up{i}", L / 2, f"{name}_down{i}", L / 2) for i in range(1, n + 1)]
    for i in range(1, n):
        joints.append(pin(f"a{i + 1}", f"{name}_down{i + 1}", 0.0, f"{name}_up{i}", L))
        joints.append(pin(f"b{i + 1}", f"{name}_up{i + 1}", 0.0, f"{name}_down{i}", L))
    points = {f"a{i}": (f"{name}_down{i}", 0.0) for i in range(1, n + 1)}
    points |= {f"b{i}": (f"{name}_up{i}", 0.0) for i in range(1, n + 1)}
    points |= {f"a{n + 1}": (f"{name}_up{n}", L), f"b{n + 1}": (f"{name}_down{n}", L)}
    points |= {f"c{i}": (f"{name}_up{i}", L / 2) for i in range(1, n + 1)}
    for key, letter, which in ENDS:
        point = f"{letter}{1 if which == 0 else n + 1}"
        body, span = points[point]
        kind = chain[key]
        if kind == "pin":
            joints.append({"type": "pin", "name": f"{name}_{point}_pin", "body": body, "span": span, "axis": "chord"})
        elif kind != "free":
            line = h if kind == "slide_across" else d
            joints.append({"type": "slider", "name": f"{name}_{point}_slider", "body": body, "span": span,
                           "line": vector(line)})
    chord = chain["section"]["axis_position"]
    probes = [{"name": f"{name}_{point}", "body": body, "span": span, "chord": chord}
              for point, (body, span) in sorted(points.items(), key=lambda item: (item[0][0], int(item[0][1:])))]
    return bodies, joints, probes


def expand_scissors(scene: dict, resolve_item) -> None:
    """Append, in place, the bodies, joints and probes of every chain of `structure.scissors` to the resolved scene.

    A scene resolved before already holds them (unchanged: nothing is added); a name that one of its tables already
    uses otherwise is a SceneError naming the chain.

    Args:
        scene: the resolved scene, changed in place.
        resolve_item: `resolve_item(section, key, raw)` resolves one raw table of the scene's array `section`
            ("bodies", "joints", "probes").
    """
    structure = scene["structure"]
    for index, chain in enumerate(structure["scissors"]):
        key = f"structure.scissors.{item_label(index, chain)}"
        if not fidelity(structure["fidelity"]).nodes_anywhere:
            raise SceneError("structure.fidelity", structure["fidelity"],
                             f"{fidelity_names(lambda f: f.nodes_anywhere)} with a scissor chain ({key}: its pins "
                             "hold nodes anywhere)")
        generated = dict(zip(("bodies", "joints", "probes"), chain_tables(structure, chain)))
        arrays = {"bodies": structure["bodies"], "joints": structure["joints"], "probes": scene["probes"]}
        resolved = {section: [resolve_item(section, f"{key}.{section}.{item['name']}", item) for item in items]
                    for section, items in generated.items()}
        present = {section: {item.get("name"): item for item in arrays[section]} for section in arrays}
        if all(present[section].get(item["name"]) == item for section, items in resolved.items() for item in items):
            continue                                   # expanded when the scene was first resolved
        for section, items in resolved.items():
            clash = next((item["name"] for item in items if item["name"] in present[section]), None)
            if clash is not None:
                raise SceneError(f"{key}.name", chain["name"], f"a name whose {section} do not clash with the scene's "
                                                               f"(it makes '{clash}', which is already used)")
            arrays[section].extend(items)
