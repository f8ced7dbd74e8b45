#!/usr/bin/env python3
"""Variety of the 4D mixed 128 preset, per stratum.

Builds a reduced copy of `manifests/4d-mixed-128.toml` with a given bettimill binary (the
preset's classes, components, bins, mode and seed; `samples` set so every stratum that can
be built gets PER_STRATUM samples; optionally a smaller side, where a class that cannot be
built at all is left out and reported; no downscaled copies and no splits, which only cost
time here), reads every sample back from the complete shards
(`KEY.json` and `KEY.npy[.zst|.gz]`) and prints, per stratum (class x components x bin):
the number of samples and min / median / max / coefficient of variation (population std
over mean) of

  (a) the chosen size parameters the label records per cavity (`construction.objects[].params`:
      `tube_radius`, `grow`, and since 0.2.0 `scale` and `thickness`; and the cavity's
      rasterised voxel count at construction, `voxels`, before any flip),
  (b) the surface-to-volume ratio of the cavities (the topology-carrying phase in carve
      mode): faces between a foreground voxel and a cavity voxel, over cavity voxels, where
      the cavities are the background voxels not connected (face adjacency) to the array's
      border, measured on the stored voxels (after all flips),
  (c) the hypervolume fraction (foreground voxels / side^4).

One command (the lead's re-run; a finished build is reused, since bettimill's build is a
no-op on a finished directory):

    /work/venv-variety/bin/python benches/variety.py --bettimill target/debug/bettimill \
        --side 64 --per-stratum 3 --workers 2 --work /tmp/variety-main --json main.json

(`--no-build` reads the complete shards of a stopped build: by default a shard holds one
sample of every stratum; with `--shard-samples 22` at side 64, where 88 strata can be
built, each 4 consecutive shards hold one sample of every stratum), and before/after side
by side as Markdown, from two such JSON files:

    /work/venv-variety/bin/python benches/variety.py --compare before.json after.json

Needs Python >= 3.11 (tomllib), numpy, and the `zstd` command for zstd members.
"""

import argparse
import io
import json
import math
import re
import subprocess
import sys
import tarfile
import tomllib
from pathlib import Path

import numpy as np

PRESET = Path(__file__).resolve().parent.parent / "manifests" / "4d-mixed-128.toml"
SIZE_PARAMS = ["tube_radius", "grow", "scale", "thickness", "voxels"]
# Parameters a family fixes by design (a ball's radius is tube_radius + grow, with the tube
# radius at its minimum): one value there is no collapse.
FIXED = {("ball", "tube_radius")}
# The statistics checked for a collapse to one value within a stratum.
COLLAPSE = ["tube_radius", "grow", "scale", "voxels", "cavity_voxels", "surface_to_volume"]


# ---------------------------------------------------------------- manifest


def toml_value(v):
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, (int, float)):
        return repr(v)
    if isinstance(v, str):
        return json.dumps(v)
    if isinstance(v, list):
        return "[" + ", ".join(toml_value(x) for x in v) + "]"
    raise TypeError(v)


def toml_dump(doc):
    """The flat schema of a manifest: scalars, tables of scalars, arrays of tables."""
    lines = [f"{k} = {toml_value(v)}" for k, v in doc.items() if not isinstance(v, dict)
             and not (isinstance(v, list) and v and isinstance(v[0], dict))]
    for k, v in doc.items():
        if isinstance(v, dict):
            lines += ["", f"[{k}]"] + [f"{a} = {toml_value(b)}" for a, b in v.items()]
        elif isinstance(v, list) and v and isinstance(v[0], dict):
            for table in v:
                lines += ["", f"[[{k}]]"] + [f"{a} = {toml_value(b)}" for a, b in table.items()]
    return "\n".join(lines) + "\n"


def expand(cls):
    """A connected_sum class table as its single (g, h, i, j) classes."""
    axes = [cls[k] if isinstance(cls[k], list) else [cls[k]] for k in "ghij"]
    return [{"family": "connected_sum", "g": g, "h": h, "i": i, "j": j}
            for g in axes[0] for h in axes[1] for i in axes[2] for j in axes[3]]


def reduced_manifest(bettimill, side, per_stratum, shard_samples, work, copies=False):
    """The preset at `side`, without splits, with PER_STRATUM samples a stratum, and
    without resolutions unless `copies` (then the preset's resolutions scaled to `side`:
    since 0.3.0 copies make carved tubes thicker, so sizes differ with and without them).
    A class that cannot be built at all at this side is left out, and so are the
    combinations the plan leaves out; both are returned, to be reported."""
    doc = tomllib.loads(PRESET.read_text())
    if copies:
        doc["resolutions"] = [r * side // doc["side"] for r in doc.get("resolutions", [])]
    else:
        doc.pop("resolutions", None)
    if doc.get("hypervolume", {}).get("unit") == "fraction":
        # The bins hold the cavities to a share of the solid inside the cube's one-voxel
        # border; at a smaller side the border takes more of the cube, so the same cavity
        # share is a smaller foreground fraction.
        inside = lambda s: ((s - 2) / s) ** doc["dimension"]
        scale = inside(side) / inside(doc["side"])
        doc["hypervolume"]["bins"] = [[round(lo * scale, 6), round(hi * scale, 6)]
                                      for lo, hi in doc["hypervolume"]["bins"]]
    doc["side"] = side
    doc.pop("splits", None)
    dropped = []
    path = work / "manifest.toml"
    for _ in range(32):
        path.write_text(toml_dump(doc))
        run = subprocess.run([bettimill, "plan", str(path), "--json"], capture_output=True,
                             text=True)
        if run.returncode == 0:
            plan = json.loads(run.stdout)
            strata = len(plan["strata"])
            # Small shards (by default one sample a stratum: the plan deals each round of
            # the strata over consecutive shards), so a stopped build is already useful.
            per_sample = side**4 + sum(r**4 for r in doc.get("resolutions", [])) + 16384
            shard_bytes = (shard_samples or strata) * per_sample
            if doc["samples"] != per_stratum * strata or doc["shard_bytes"] != shard_bytes:
                doc["samples"] = per_stratum * strata
                doc["shard_bytes"] = shard_bytes
                continue
            left_out = [x if isinstance(x, str) else x.get("label", str(x))
                        for x in plan.get("infeasible", [])]
            return path, strata, dropped + left_out
        m = re.search(r"class (\d+) \((connected_sum\(g=(\d+),h=(\d+),i=(\d+),j=(\d+)\))\)[^\n]*"
                      r"does not fit", run.stderr)
        if not m:
            sys.exit(f"bettimill plan refused the reduced preset:\n{run.stderr}")
        g, h, i, j = (int(m.group(k)) for k in range(3, 7))
        classes = []
        for cls in doc["classes"]:
            if cls["family"] == "connected_sum":
                classes += [c for c in expand(cls) if (c["g"], c["h"], c["i"], c["j"])
                            != (g, h, i, j)]
            else:
                classes.append(cls)
        doc["classes"] = classes
        dropped.append(m.group(2))
    sys.exit("could not reduce the preset")


# ---------------------------------------------------------------- samples


def read_npy(name, data):
    if name.endswith(".zst"):
        data = subprocess.run(["zstd", "-dcq"], input=data, capture_output=True,
                              check=True).stdout
    elif name.endswith(".gz"):
        import gzip
        data = gzip.decompress(data)
    return np.load(io.BytesIO(data), allow_pickle=False)


def samples(directory):
    """(label, voxels) of every sample of every complete shard (one with its completion
    record), in key order."""
    for shard in sorted((directory / "shards").glob("*.tar")):
        if not (directory / "records" / (shard.stem + ".json")).exists():
            continue
        with tarfile.open(shard) as tar:
            pending = {}
            for member in tar:
                key, _, field = member.name.partition(".")
                data = tar.extractfile(member).read()
                entry = pending.setdefault(key, {})
                if field == "json":
                    entry["label"] = json.loads(data)
                elif field in ("npy", "npy.zst", "npy.gz"):
                    entry["voxels"] = read_npy(member.name, data)
                if "label" in entry and "voxels" in entry:
                    yield entry["label"], entry["voxels"]
                    del pending[key]


def shifted(a, axis, lo):
    """The slices a[..., :-1, ...] (lo) or a[..., 1:, ...] along `axis`."""
    index = [slice(None)] * a.ndim
    index[axis] = slice(None, -1) if lo else slice(1, None)
    return tuple(index)


def cavities(voxels):
    """Background voxels not face-connected to the array's border."""
    bg = voxels == 0
    outside = np.zeros_like(bg)
    # Seeds: background voxels seen from a face of the array along an axis.
    for axis in range(bg.ndim):
        outside |= np.logical_and.accumulate(bg, axis=axis)
        outside |= np.flip(np.logical_and.accumulate(np.flip(bg, axis), axis=axis), axis)
    count = np.count_nonzero(outside)
    while True:  # grow inside the background until nothing changes
        grown = outside.copy()
        for axis in range(bg.ndim):
            lo, hi = shifted(bg, axis, True), shifted(bg, axis, False)
            grown[hi] |= outside[lo]
            grown[lo] |= outside[hi]
        grown &= bg
        new = np.count_nonzero(grown)
        if new == count:
            break
        outside, count = grown, new
    return bg & ~outside


def inertia_ratios(mask):
    """The eigenvalues of the covariance of the voxel coordinates of `mask`, each over the
    largest, in decreasing order (1 first): all near 1 for a round phase, small for a
    flat or thin one."""
    coords = np.argwhere(mask).astype(float)
    if len(coords) < 2:
        return [float("nan")] * (mask.ndim - 1)
    eig = np.sort(np.linalg.eigvalsh(np.cov(coords, rowvar=False)))[::-1]
    return [float(e / eig[0]) for e in eig[1:]]


def shape_stats(voxels):
    """Surface-to-volume ratio, inertia ratios and voxel count of the cavities."""
    cav = cavities(voxels)
    fg = voxels != 0
    faces = 0
    for axis in range(voxels.ndim):
        lo, hi = shifted(fg, axis, True), shifted(fg, axis, False)
        faces += np.count_nonzero(fg[lo] & cav[hi]) + np.count_nonzero(cav[lo] & fg[hi])
    cavity_voxels = int(np.count_nonzero(cav))
    ratios = inertia_ratios(cav)
    return cav, {
        "cavity_voxels": cavity_voxels,
        "cavity_faces": int(faces),
        "surface_to_volume": faces / cavity_voxels if cavity_voxels else float("nan"),
        "inertia_mid": ratios[0],
        "inertia_min": ratios[-1],
    }


def sample_stats(label, voxels, construction=None):
    """The statistics of one sample; with `construction` (its undeformed voxels), also
    those of the construction (`before`) and the voxel IoU of the two's cavities."""
    cav, shape = shape_stats(voxels)
    objects = label["construction"].get("objects", [])
    params = {p: [] for p in SIZE_PARAMS}
    for obj in objects:
        for p in SIZE_PARAMS:
            value = obj.get(p, obj.get("params", {}).get(p))
            if isinstance(value, (int, float)):
                params[p].append(float(value))
    bin_lo, bin_hi = label["hypervolume_bin"]
    record = {
        "key": label["key"],
        "tool_version": label["tool_version"],
        "stratum": label["class_label"],
        "family": label["class_label"].split("/")[0],
        "components": label["components"],
        "bin": [bin_lo, bin_hi],
        "betti": label["betti"],
        "hypervolume_fraction": label["hypervolume"] / voxels.size,
        **shape,
        "params": {p: v for p, v in params.items() if v},
    }
    if construction is not None:
        cav0, before = shape_stats(construction)
        record["before"] = before
        union = np.count_nonzero(cav | cav0)
        record["iou"] = float(np.count_nonzero(cav & cav0) / union) if union else float("nan")
    return record


# ---------------------------------------------------------------- tables


def summary(values):
    v = np.array(values, dtype=float)
    mean = v.mean()
    cv = float(v.std() / mean) if mean else float("nan")
    return {"n": len(v), "min": float(v.min()), "median": float(np.median(v)),
            "max": float(v.max()), "cv": cv}


def stratum_order(records):
    """Strata in the order they first appear in the keys (= plan order for the first round)."""
    order = {}
    for r in records:
        order.setdefault(r["stratum"], len(order))
    return sorted(order, key=order.get)


def bin_name(record, side, dim=4):
    lo, hi = record["bin"]
    return f"{lo / side**dim:.0%}-{(hi + 1) / side**dim:.0%}"


def stratum_name(record, side):
    return f"{record['family']} x{record['components']} {bin_name(record, side)}"


def per_stratum(records):
    out = {}
    for name in stratum_order(records):
        rs = [r for r in records if r["stratum"] == name]
        entry = {"samples": len(rs), "first": rs[0]}
        for stat in ("surface_to_volume", "hypervolume_fraction", "cavity_voxels",
                     "inertia_mid", "inertia_min", "iou"):
            if all(stat in r for r in rs):
                entry[stat] = summary([r[stat] for r in rs])
        for stat in ("surface_to_volume", "cavity_voxels", "inertia_mid", "inertia_min"):
            if all("before" in r for r in rs):
                entry["before_" + stat] = summary([r["before"][stat] for r in rs])
        for p in SIZE_PARAMS:
            vals = [v for r in rs for v in r["params"].get(p, [])]
            if vals:
                entry[p] = summary(vals)
        out[name] = entry
    return out


def fmt(x):
    if isinstance(x, float) and math.isnan(x):
        return "-"
    if abs(x) >= 1000:
        return f"{x:.0f}"
    return f"{x:.3g}"


def print_table(result):
    side = result["side"]
    print(f"bettimill {result['tool_version']}, side {side}, {result['samples']} samples, "
          f"{result['strata']} strata ({result['per_stratum']} a stratum)")
    if result["dropped"]:
        print("left out (cannot be built at this side):", "; ".join(result["dropped"]))
    stats = ["tube_radius", "grow", "scale", "thickness", "voxels", "cavity_voxels",
             "surface_to_volume", "hypervolume_fraction", "inertia_mid", "inertia_min",
             "before_cavity_voxels", "before_surface_to_volume", "before_inertia_mid",
             "before_inertia_min", "iou"]
    for name, entry in per_stratum(result["records"]).items():
        print(f"{stratum_name(entry['first'], side)}  (n={entry['samples']})")
        for stat in stats:
            if stat in entry:
                s = entry[stat]
                print(f"    {stat:21} n {s['n']:2}  min {fmt(s['min']):>8}  median "
                      f"{fmt(s['median']):>8}  max {fmt(s['max']):>8}  cv {fmt(s['cv']):>6}")
    collapses(result)


def collapsed(entries, side):
    """{statistic: [strata]} where a statistic takes one value in the stratum (min = max,
    over more than one value; family-fixed parameters excepted)."""
    found = {}
    for entry in entries.values():
        for stat in COLLAPSE:
            s = entry.get(stat)
            if s and s["n"] > 1 and s["min"] == s["max"] \
                    and (entry["first"]["family"], stat) not in FIXED:
                found.setdefault(stat, []).append(stratum_name(entry["first"], side))
    return found


def collapses(result):
    found = collapsed(per_stratum(result["records"]), result["side"])
    print(f"statistics with one value in a stratum (min = max): "
          f"{sum(len(v) for v in found.values())}")
    for stat, strata in found.items():
        print(f"    {stat}: {len(strata)}: {', '.join(strata)}")


def cell(entry, stat, spread=True):
    if stat not in entry:
        return "-"
    s = entry[stat]
    if spread:
        return f"{fmt(s['min'])}-{fmt(s['max'])} ({fmt(s['cv'])})"
    return f"{fmt(s['median'])} ({fmt(s['cv'])})"


def compare(before, after):
    """Markdown: one row per stratum, before | after for each statistic."""
    b, a = per_stratum(before["records"]), per_stratum(after["records"])
    side = after["side"]
    print(f"Before: bettimill {before['tool_version']}, after: {after['tool_version']}; "
          f"side {side}; cells are min-max (coefficient of variation), S/V median (cv); "
          f"n samples before/after; cavity voxels measured on the stored voxels.\n")
    print("| stratum | n | tube radius before | after | grow before | after | scale after "
          "| cavity voxels before | after | cavity S/V before | after | hv fraction before "
          "| after |")
    print("|---|---|---|---|---|---|---|---|---|---|---|---|---|")
    for name in stratum_order(after["records"]) + [n for n in b if n not in a]:
        eb, ea = b.get(name, {}), a.get(name, {})
        first = (ea or eb)["first"]
        n = f"{eb.get('samples', 0)}/{ea.get('samples', 0)}"
        print(f"| {stratum_name(first, side)} | {n} | {cell(eb, 'tube_radius')} | "
              f"{cell(ea, 'tube_radius')} | {cell(eb, 'grow')} | {cell(ea, 'grow')} | "
              f"{cell(ea, 'scale')} | {cell(eb, 'cavity_voxels')} | {cell(ea, 'cavity_voxels')} | "
              f"{cell(eb, 'surface_to_volume', False)} | {cell(ea, 'surface_to_volume', False)} | "
              f"{cell(eb, 'hypervolume_fraction')} | {cell(ea, 'hypervolume_fraction')} |")
    for label, entries in (("before", b), ("after", a)):
        zero = collapsed(entries, side)
        print(f"\n{label}: strata where a statistic takes one value (of {len(entries)} strata): "
              + ("; ".join(f"{k} {len(v)} ({', '.join(v)})" for k, v in zero.items()) or "none"))


def deformation_table(result):
    """Markdown: per stratum, the cavities' shape statistics of the undeformed
    constructions against the built samples, and their voxel IoU."""
    side = result["side"]
    entries = per_stratum(result["records"])
    print(f"bettimill {result['tool_version']}, side {side}, {result['samples']} samples; "
          f"cells are median (coefficient of variation) over the stratum's samples; "
          f"construction = the same sample before deformation and targeting.\n")
    print("| stratum | n | S/V construction | S/V sample | l2/l1 construction | l2/l1 sample "
          "| lmin/l1 construction | lmin/l1 sample | cavity IoU median (min-max) |")
    print("|---|---|---|---|---|---|---|---|---|")
    for entry in entries.values():
        iou = entry["iou"]
        print(f"| {stratum_name(entry['first'], side)} | {entry['samples']} | "
              f"{cell(entry, 'before_surface_to_volume', False)} | "
              f"{cell(entry, 'surface_to_volume', False)} | "
              f"{cell(entry, 'before_inertia_mid', False)} | {cell(entry, 'inertia_mid', False)} | "
              f"{cell(entry, 'before_inertia_min', False)} | {cell(entry, 'inertia_min', False)} | "
              f"{fmt(iou['median'])} ({fmt(iou['min'])}-{fmt(iou['max'])}) |")
    ious = [r["iou"] for r in result["records"]]
    spread = {}
    for stat in ("surface_to_volume", "inertia_min"):
        for when, get in (("construction", lambda r: r["before"][stat]),
                          ("sample", lambda r: r[stat])):
            # The spread within strata: the mean over strata of the coefficient of variation.
            cvs = [summary([get(r) for r in result["records"] if r["stratum"] == name])["cv"]
                   for name in entries]
            spread[(stat, when)] = float(np.nanmean(cvs))
    print(f"\nall samples: cavity IoU with the construction mean {np.mean(ious):.3f}, "
          f"median {np.median(ious):.3f}, max {np.max(ious):.3f}; mean within-stratum cv of "
          f"S/V {spread[('surface_to_volume', 'construction')]:.3f} -> "
          f"{spread[('surface_to_volume', 'sample')]:.3f}, of lmin/l1 "
          f"{spread[('inertia_min', 'construction')]:.3f} -> "
          f"{spread[('inertia_min', 'sample')]:.3f}")


# ---------------------------------------------------------------- main


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--bettimill", help="the bettimill binary that builds the samples")
    ap.add_argument("--side", type=int, default=128)
    ap.add_argument("--per-stratum", type=int, default=3)
    ap.add_argument("--copies", action="store_true",
                    help="keep the preset's resolutions, scaled to --side (sizes as the preset builds them)")
    ap.add_argument("--workers", type=int, default=1)
    ap.add_argument("--work", type=Path, help="scratch directory (kept; a finished build is reused)")
    ap.add_argument("--json", type=Path, help="write the per-sample statistics here")
    ap.add_argument("--shard-samples", type=int,
                    help="samples a shard (default: the number of strata)")
    ap.add_argument("--no-build", action="store_true",
                    help="only read the complete shards already in --work (of a stopped build)")
    ap.add_argument("--iou", action="store_true",
                    help="also measure every sample's undeformed construction (needs the "
                         "bettimill Python package of the same version) and print the "
                         "deformation table")
    ap.add_argument("--compare", nargs=2, type=Path, metavar=("BEFORE", "AFTER"),
                    help="print before/after as Markdown from two --json files; builds nothing")
    args = ap.parse_args()
    if args.compare:
        before, after = (json.loads(p.read_text()) for p in args.compare)
        compare(before, after)
        return
    if not args.bettimill or not args.work:
        ap.error("--bettimill and --work are needed (or --compare)")
    args.work.mkdir(parents=True, exist_ok=True)
    manifest, strata, dropped = reduced_manifest(args.bettimill, args.side, args.per_stratum,
                                                 args.shard_samples, args.work, args.copies)
    out = args.work / "dataset"
    build = [args.bettimill, "build", str(manifest), "--out", str(out), "--workers",
             str(args.workers), "--quiet"]
    print("$", " ".join(build), file=sys.stderr, flush=True)
    if not args.no_build:
        subprocess.run(build, check=True, stdout=subprocess.DEVNULL)
    construction = lambda label: None
    if args.iou:
        import bettimill
        plan = bettimill.Plan(str(manifest))
        index = out / "index.json"  # absent while a build is unfinished
        if index.exists() and plan.manifest_hash != json.loads(index.read_text())["manifest_hash"]:
            sys.exit("the dataset was built from another manifest")
        construction = lambda label: plan.construction(int(label["key"][1:]), label["attempt"])
    records = [sample_stats(label, voxels, construction(label))
               for label, voxels in samples(out)]
    if not records:
        sys.exit(f"no complete shard in {out}")
    result = {"tool_version": records[0]["tool_version"], "side": args.side,
              "per_stratum": args.per_stratum, "strata": strata, "samples": len(records),
              "command": " ".join(build),
              "dropped": dropped, "records": records}
    if args.json:
        args.json.write_text(json.dumps(result, indent=1) + "\n")
    print_table(result)
    if args.iou:
        deformation_table(result)


if __name__ == "__main__":
    main()
