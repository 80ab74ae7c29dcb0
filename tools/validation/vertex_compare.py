#!/usr/bin/env python3
"""Per-vertex comparison of prt relight's radiance with Cycles' (docs/validation.md, "Per vertex").

    python3 tools/validation/vertex_compare.py CYCLES.csv PRT.csv [--name S] [--floor F] [--json OUT.json]

CYCLES.csv: tools/validation/cycles_vertex_reference.py (one colour per seed); PRT.csv: `prt relight --csv`
(docs/formats.md). Standard library only.

Matching: a Cycles vertex and a prt row match when their positions agree to 0.1 mm and their
normals to 0.01 (the same glTF vertex; prt's refinement adds vertices that Cycles has not, and
they are left out). Vertices where surfaces meet (a position that the Cycles scene holds with
two different normals: room corners, box edges) are reported apart and left out of the main
figures: there both renderers' results depend on how rays leave a point on two surfaces. So
are the vertices that two objects hold with the same normal (the rim of an emissive panel set
into a ceiling: the position and normal do not tell which object's prt row is which).

Metric: luminance Y = 0.2126 R + 0.7152 G + 0.0722 B of the exitant radiance; Cycles' value is
the mean of its seeds. Per vertex the relative error e = (Y_prt - Y_cycles) / Y_cycles, over the
vertices with Y_cycles >= F x the median Y_cycles (default F = 0.02: inside the boxes, under
them, and in the darkest corners both are ~0 and the ratio is noise). Reported: the median and
95th percentile of |e|, the mean of e (bias), and Cycles' noise: the per-vertex standard error of
its mean, estimated from the seeds as |Y_1 - Y_2| / 2 / Y (two seeds), as its median and p95
over the same vertices (an error of the size of the noise is not resolved).
"""

import csv
import json
import math
import sys


def lum(r, g, b):
    return 0.2126 * r + 0.7152 * g + 0.0722 * b


def key(p, n):
    return tuple(round(v * 1e4) for v in p) + tuple(round(v * 1e2) for v in n)


def pct(values, q):
    if not values:
        return float("nan")
    v = sorted(values)
    return v[min(len(v) - 1, int(round(q * (len(v) - 1))))]


def main(argv):
    if len(argv) < 2:
        sys.exit(__doc__)
    cyc_path, prt_path, name, floor_f, json_out = argv[0], argv[1], argv[1], 0.02, None
    i = 2
    while i < len(argv):
        if argv[i] == "--name": name = argv[i + 1]
        elif argv[i] == "--floor": floor_f = float(argv[i + 1])
        elif argv[i] == "--json": json_out = argv[i + 1]
        else: sys.exit(f"vertex_compare.py: unknown argument {argv[i]}")
        i += 2
    with open(cyc_path) as f:
        cyc = list(csv.DictReader(f))
    seeds = sorted({k[2:] for k in cyc[0] if k.startswith("r_")})
    prt = {}
    with open(prt_path) as f:
        for row in csv.DictReader(f):
            p = tuple(float(row[c]) for c in ("px", "py", "pz"))
            n = tuple(float(row[c]) for c in ("nx", "ny", "nz"))
            prt[key(p, n)] = lum(float(row["r"]), float(row["g"]), float(row["b"]))
    normals_at, objects_at = {}, {}
    for row in cyc:
        p = tuple(round(float(row[c]) * 1e4) for c in ("px", "py", "pz"))
        normals_at.setdefault(p, set()).add(tuple(round(float(row[c]) * 1e2) for c in ("nx", "ny", "nz")))
        objects_at.setdefault(p, set()).add(row["object"])
    verts, missing = [], 0
    for row in cyc:
        p = tuple(float(row[c]) for c in ("px", "py", "pz"))
        n = tuple(float(row[c]) for c in ("nx", "ny", "nz"))
        ys = [lum(float(row["r_" + s]), float(row["g_" + s]), float(row["b_" + s])) for s in seeds]
        k = key(p, n)
        if k not in prt:
            missing += 1
            continue
        at = tuple(round(v * 1e4) for v in p)
        edge = len(normals_at[at]) > 1 or len(objects_at[at]) > 1
        verts.append({"object": row["object"], "edge": edge, "cycles": sum(ys) / len(ys),
                      "se": abs(ys[0] - ys[1]) / 2 if len(ys) == 2 else float("nan"), "prt": k and prt[k]})
    inner = [v for v in verts if not v["edge"]]
    floor = floor_f * pct([v["cycles"] for v in inner], 0.5)

    def summary(vs):
        vs = [v for v in vs if v["cycles"] >= floor]
        e = [(v["prt"] - v["cycles"]) / v["cycles"] for v in vs]
        s = [v["se"] / v["cycles"] for v in vs]
        return {"vertices": len(vs), "median": pct([abs(x) for x in e], 0.5), "p95": pct([abs(x) for x in e], 0.95),
                "bias": sum(e) / len(e) if e else float("nan"), "noise_median": pct(s, 0.5), "noise_p95": pct(s, 0.95),
                "cycles_mean": sum(v["cycles"] for v in vs) / max(len(vs), 1),
                "prt_mean": sum(v["prt"] for v in vs) / max(len(vs), 1)}

    out = {"name": name, "matched": len(verts), "unmatched_cycles": missing, "floor": floor,
           "floor_fraction_of_median": floor_f, "dark_skipped": sum(1 for v in inner if v["cycles"] < floor),
           "all": summary(inner), "edges": summary([v for v in verts if v["edge"]]), "objects": {}}
    for obj in sorted({v["object"] for v in inner}):
        out["objects"][obj] = summary([v for v in inner if v["object"] == obj])
    print(f"== {name}: {len(verts)} vertices matched ({missing} of Cycles' unmatched), {len(inner)} away from edges, "
          f"{out['dark_skipped']} of them below the floor {floor:.3g} ({100 * floor_f:g}% of the median)")
    print(f"   {'group':12s} {'verts':>5s} {'median|e|':>9s} {'p95|e|':>8s} {'bias':>7s} {'noise med':>9s} {'p95':>6s} "
          f"{'Y cycles':>9s} {'Y prt':>9s}")
    rows = [("all", out["all"])] + list(out["objects"].items()) + [("(edges)", out["edges"])]
    for label, s in rows:
        print(f"   {label:12s} {s['vertices']:5d} {100 * s['median']:8.1f}% {100 * s['p95']:7.1f}% {100 * s['bias']:+6.1f}% "
              f"{100 * s['noise_median']:8.1f}% {100 * s['noise_p95']:5.1f}% {s['cycles_mean']:9.4f} {s['prt_mean']:9.4f}")
    if json_out:
        with open(json_out + ".tmp", "w") as f:
            json.dump(out, f, indent=1)
        import os
        os.replace(json_out + ".tmp", json_out)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
