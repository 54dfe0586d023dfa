#!/usr/bin/env python3
"""The localization protocol suite: every protocol x every method, one table.

Runs the default recipe (sift_densevlad.yaml, both solvers) and COLMAP classic
(colmap_classic.yaml) on each protocol, one run after the other, each in a
fresh workspace, and writes SUITE/suite.md and SUITE/suite.csv: recall at the
paper's three thresholds (and at object thresholds where the scene is an
object), median position and rotation error, CPU and wall seconds.

  python3 configs/benchmark/suite.py --workspace SUITE
  python3 configs/benchmark/suite.py --workspace SUITE --protocols strecha_castle-P30_sparse \
      --methods ours --set map_matches.ratio=0.9     # an ablation on one protocol

The rule this table serves: a changed default re-runs the whole suite, and a
default that loses to COLMAP classic anywhere is not a default.
"""
import argparse
import csv
import json
import math
import os
import resource
import shutil
import subprocess
import sys
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]
PAPER = [(0.10, 1.0), (0.25, 2.0), (1.0, 5.0)]
OBJECT = [(0.005, 0.5), (0.01, 1.0), (0.02, 2.0)]  # object-centred scenes, 0.5-1 m away
SIM_SPARSE = ["--set", "map_sample_every=4", "--set", "query_sample_every=4",
              "--set", "query_sample_rest=true", "--set", "groups=[industrial=ind_.*, phone=phone_.*]"]


def protocols(shared):
    """name -> (map, query, extra --set args, recording to make first, thresholds)."""
    loc = shared / "data/localization"
    vg = shared / "data/kapture/virtual_gallery_tutorial"
    out = {}
    for name in ["strecha_castle-P30_sparse", "strecha_Herz-Jesus-P25", "strecha_fountain-P11",
                 "strecha_entry-P10"]:
        out[name] = dict(map=loc / name / "mapping", query=loc / name / "query", args=[],
                         recording=None, thresholds=PAPER)
    out["dtu_scan24_sparse"] = dict(map=loc / "dtu_scan24_sparse/mapping",
                                    query=loc / "dtu_scan24_sparse/query", args=[],
                                    recording=None, thresholds=PAPER + OBJECT)
    out["virtual_gallery_tutorial"] = dict(map=vg / "mapping", query=vg / "query", args=[],
                                           recording=None, thresholds=PAPER)
    out["sim_sparse_map"] = dict(map="REC", query="REC", args=SIM_SPARSE, thresholds=PAPER,
                                 recording=["configs/sim/small.yaml", "--set", "seed=7",
                                            "--set", "recording.duration_scale=0.25"])
    out["sim_crowded_sparse_map"] = dict(map="REC", query="REC", args=SIM_SPARSE, thresholds=PAPER,
                                         recording=["configs/sim/small.yaml", "--set", "seed=11",
                                                    "--set", "crowdedness=12",
                                                    "--set", "recording.duration_scale=0.25"])
    # The demo's benchmark: map and queries from the demo's own ground truth.
    out["demo_tiny"] = dict(map="GT", query="GT", thresholds=PAPER,
                            args=["--set", "map_images=map_.*", "--set", "query_images=(val|test)_.*",
                                  "--set", "groups=[industrial=ind_.*, smartphone=phone_.*]"],
                            recording=["configs/demo.yaml"])
    return out


def r2d2_model(args, checkpoint="faster2d2_WASF_N16"):
    """One of the R2D2 checkpoints ../shared/models/r2d2 holds."""
    return args.shared / f"models/r2d2/{checkpoint}.onnx"


def built_model(args, name):
    """A model the build exports beside its bin/ (build/models/NAME)."""
    return Path(args.locforge).resolve().parent.parent / "models" / name


METHODS = {
    # name: (graph, [(row label, eval node)], args -> extra --set values)
    "ours": ("configs/benchmark/sift_densevlad.yaml",
             [("ours (pnp)", "eval_pnp"), ("ours, image_registrator", "eval_colmap")], lambda a: a.set),
    "colmap_classic": ("configs/benchmark/colmap_classic.yaml", [("COLMAP classic", "eval")], lambda a: []),
    # The learned rows: the default recipe with other local features and the authors' plain
    # mutual NN (ratio 1); not judged against COLMAP (the default is SIFT).
    "xfeat": ("configs/benchmark/xfeat_densevlad.yaml", [("XFeat (pnp)", "eval_pnp")],
              lambda a: [f"xfeat_model={built_model(a, 'xfeat.onnx')}"]),
    "alike_n": ("configs/benchmark/alike_densevlad.yaml", [("ALIKE-n (pnp)", "eval_pnp")],
                lambda a: [f"alike_model={built_model(a, 'alike-n.onnx')}"]),
    # R2D2 at the authors' extraction settings (the stage's defaults: pyramid 0.25-1 within
    # 256-1024 px, thresholds 0.7, top 5000): "r2d2_wasf" with the authors' default weights
    # (r2d2_WASF_N16), "r2d2" with the ~2.5x cheaper faster2d2 weights.
    "r2d2_wasf": ("configs/benchmark/sift_densevlad.yaml", [("R2D2 r2d2_WASF_N16 (pnp)", "eval_pnp")],
                  lambda a: ["ratio=1", "method=r2d2_wasf+densevlad",
                             f"local_features={{stage: features/r2d2, params: "
                             f"{{model: {r2d2_model(a, 'r2d2_WASF_N16')}}}}}"]),
    "r2d2": ("configs/benchmark/sift_densevlad.yaml", [("R2D2 faster2d2 (pnp)", "eval_pnp")],
             lambda a: ["ratio=1", "method=r2d2+densevlad",
                        f"local_features={{stage: features/r2d2, params: {{model: {r2d2_model(a)}}}}}"]),
}


def run(cmd, log):
    """Runs cmd, returns (exit code, wall s, CPU s of it and its children)."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    start = time.monotonic()
    with open(log, "w") as f:
        code = subprocess.call(cmd, stdout=f, stderr=subprocess.STDOUT)
    wall = time.monotonic() - start
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    return code, wall, cpu


def recall(rows, pos_m, rot_deg):
    ok = sum(1 for r in rows if r["localized"] == "1" and float(r["position_error_m"]) <= pos_m
             and float(r["rotation_error_deg"]) <= rot_deg)
    return 100.0 * ok / max(1, len(rows))


def median(values):
    v = sorted(values)
    if not v:
        return float("nan")
    n = len(v)
    return v[n // 2] if n % 2 else 0.5 * (v[n // 2 - 1] + v[n // 2])


def score(per_query_csv, thresholds):
    with open(per_query_csv) as f:
        rows = list(csv.DictReader(f))
    located = [r for r in rows if r["localized"] == "1"]
    return dict(queries=len(rows), localized=len(located),
                errors={r["image"]: (float(r["position_error_m"]), float(r["rotation_error_deg"])) for r in located},
                recall=[recall(rows, p, a) for p, a in thresholds],
                median_m=median([float(r["position_error_m"]) for r in located]),
                median_deg=median([float(r["rotation_error_deg"]) for r in located]))


def ensure_recording(args, name, spec):
    """The data a simulator protocol runs on, made once under SUITE/_data/NAME."""
    ws = args.workspace / "_data" / name
    ws.parent.mkdir(parents=True, exist_ok=True)
    if not (ws / "nodes").exists() or args.fresh_data:
        print(f"[{name}] making its data: locforge run {' '.join(spec['recording'])}", flush=True)
        code, wall, _ = run([str(args.locforge), "run", str(REPO / spec["recording"][0]),
                             "--workspace", str(ws), "--threads", str(args.threads)] +
                            spec["recording"][1:], ws.parent / f"{name}.log")
        if code != 0:
            sys.exit(f"[{name}] making its data failed: see {ws.parent / (name + '.log')}")
    if spec["map"] == "GT":
        return ws / "nodes/gt/dataset" if (ws / "nodes/gt/dataset").exists() else ws / "nodes/gt"
    return ws / "nodes/recording"


def main():
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--workspace", type=Path, required=True, help="folder of every run and the table")
    p.add_argument("--locforge", type=Path, default=REPO / "build/bin/locforge")
    p.add_argument("--shared", type=Path, default=REPO.parent / "shared")
    p.add_argument("--protocols", default="", help="comma-separated subset (default: all)")
    p.add_argument("--methods", default="ours,colmap_classic",
                   help="comma-separated subset of " + ", ".join(METHODS))
    p.add_argument("--threads", type=int, default=2)
    p.add_argument("--set", action="append", default=[], help="extra --set for the 'ours' graph")
    p.add_argument("--reuse", nargs="?", const="all", default="",
                   help="keep these methods' finished runs (comma-separated; no value: every method) "
                        "and their recorded times when their command is unchanged, instead of re-running them")
    p.add_argument("--fresh-data", action="store_true", help="re-make the simulator recordings")
    args = p.parse_args()
    args.workspace = args.workspace.resolve()
    args.workspace.mkdir(parents=True, exist_ok=True)
    all_protocols = protocols(args.shared.resolve())
    names = [n for n in args.protocols.split(",") if n] or list(all_protocols)
    for n in names:
        if n not in all_protocols:
            sys.exit(f"unknown protocol '{n}'; known: {', '.join(all_protocols)}")
    methods = [m for m in args.methods.split(",") if m]
    for m in methods:
        if m not in METHODS:
            sys.exit(f"unknown method '{m}'; known: {', '.join(METHODS)}")

    results = []
    for name in names:
        spec = all_protocols[name]
        data = ensure_recording(args, name, spec) if spec["recording"] else None
        map_dir = data if spec["map"] in ("REC", "GT") else spec["map"]
        query_dir = data if spec["query"] in ("REC", "GT") else spec["query"]
        for method in methods:
            graph, rows, extra_sets = METHODS[method]
            ws = args.workspace / name / method
            timing = ws / "suite_run.json"
            extra = [a for s in extra_sets(args) for a in ("--set", s)]
            cmd = [str(args.locforge), "run", str(REPO / graph), "--workspace", str(ws),
                   "--threads", str(args.threads), "--set", f"map={map_dir}",
                   "--set", f"query={query_dir}"] + spec["args"] + extra
            reuse = args.reuse == "all" or method in args.reuse.split(",")
            if reuse and timing.exists() and json.loads(timing.read_text())["cmd"] == cmd:
                t = json.loads(timing.read_text())
            else:
                if ws.exists():
                    shutil.rmtree(ws)
                ws.mkdir(parents=True)
                print(f"[{name}] {method}: {' '.join(cmd)}", flush=True)
                code, wall, cpu = run(cmd, ws / "suite_run.log")
                if code != 0:
                    print(f"[{name}] {method} failed (exit {code}): see {ws / 'suite_run.log'}", flush=True)
                    continue
                t = dict(cmd=cmd, wall_s=wall, cpu_s=cpu, finished=time.strftime("%Y-%m-%d %H:%M:%S UTC", time.gmtime()))
                tmp = timing.with_suffix(".tmp")
                tmp.write_text(json.dumps(t, indent=1))
                os.replace(tmp, timing)
            feat_cpu, feat_wall = feature_seconds(ws)
            for label, node in rows:
                s = score(ws / "nodes" / node / "per_query.csv", spec["thresholds"])
                results.append(dict(protocol=name, method=label, wall_s=t["wall_s"], cpu_s=t["cpu_s"],
                                    feat_cpu=feat_cpu, feat_wall=feat_wall,
                                    thresholds=spec["thresholds"], first=(label == rows[0][0]), **s))
            print(f"[{name}] {method}: {t['wall_s']:.0f} s wall", flush=True)
    write_tables(args.workspace, results)


def fmt_recall(r):
    return " / ".join(f"{x:.1f}" for x in r)


def verdict(ours, colmap):
    """Whether ours holds against COLMAP classic: recall, medians, wall <= 1/3."""
    notes = []
    if any(a < b - 1e-9 for a, b in zip(ours["recall"], colmap["recall"])):
        notes.append("recall below")
    if ours["median_m"] > colmap["median_m"]:
        notes.append("median position above")
    if ours["median_deg"] > colmap["median_deg"]:
        notes.append("median rotation above")
    if ours["wall_s"] > colmap["wall_s"] / 3:
        notes.append("wall > 1/3")
    return "holds" if not notes else "LOSES: " + ", ".join(notes)


def feature_seconds(ws):
    """Local features' CPU and wall seconds per image (the *_features nodes' manifests)."""
    cpu = wall = items = 0
    for manifest in ws.glob("nodes/*_features/.locforge-complete"):
        m = json.loads(manifest.read_text())
        cpu, wall, items = cpu + m["cpu_seconds"], wall + m["seconds"], items + m["items"]
    return (cpu / items, wall / items) if items else (float("nan"), float("nan"))


def closer(ours, colmap):
    """Queries where ours is closer to the truth than COLMAP classic, in position and in rotation
    (a query only one of them localized counts for that one): the paired view of two medians."""
    images = set(ours["errors"]) | set(colmap["errors"])
    inf = (float("inf"), float("inf"))
    pos = sum(ours["errors"].get(i, inf)[0] < colmap["errors"].get(i, inf)[0] for i in images)
    rot = sum(ours["errors"].get(i, inf)[1] < colmap["errors"].get(i, inf)[1] for i in images)
    return f"{pos} / {rot} of {len(images)}"


def write_tables(root, results):
    header = ["protocol", "method", "queries", "localized", "recall (paper thresholds) %",
              "recall (object thresholds) %", "median position", "median rotation", "CPU s", "wall s",
              "features s / image: CPU, wall", "wall / COLMAP's", "against COLMAP classic",
              "queries closer than COLMAP: position / rotation"]
    by = {(r["protocol"], r["method"]): r for r in results}
    lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    with open(root / "suite.csv.tmp", "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["protocol", "method", "queries", "localized", "recall_0.1m_1deg", "recall_0.25m_2deg",
                    "recall_1m_5deg", "recall_5mm_0.5deg", "recall_1cm_1deg", "recall_2cm_2deg",
                    "median_position_m", "median_rotation_deg", "cpu_s", "wall_s",
                    "features_cpu_s_per_image", "features_wall_s_per_image"])
        for r in results:
            colmap = by.get((r["protocol"], "COLMAP classic"))
            paper, obj = r["recall"][:3], r["recall"][3:]
            ratio = f"{r['wall_s'] / colmap['wall_s']:.2f}" if colmap and r["first"] and r is not colmap else ""
            against = verdict(r, colmap) if colmap and r["method"] == "ours (pnp)" else ""
            timed = r["first"]
            lines.append("| " + " | ".join([
                r["protocol"], r["method"], str(r["queries"]), str(r["localized"]), fmt_recall(paper),
                fmt_recall(obj) if obj else "", f"{1000 * r['median_m']:.2f} mm", f"{r['median_deg']:.4f} deg",
                f"{r['cpu_s']:.0f}" if timed else "(same run)", f"{r['wall_s']:.0f}" if timed else "",
                f"{r['feat_cpu']:.2f}, {r['feat_wall']:.2f}" if timed and not math.isnan(r["feat_cpu"]) else "",
                ratio, against, closer(r, colmap) if against else ""]) + " |")
            w.writerow([r["protocol"], r["method"], r["queries"], r["localized"]] + paper +
                       (obj if obj else ["", "", ""]) + [r["median_m"], r["median_deg"],
                                                         r["cpu_s"] if timed else "", r["wall_s"] if timed else "",
                                                         r["feat_cpu"] if timed else "", r["feat_wall"] if timed else ""])
    os.replace(root / "suite.csv.tmp", root / "suite.csv")
    text = "\n".join(lines) + "\n"
    (root / "suite.md.tmp").write_text(text)
    os.replace(root / "suite.md.tmp", root / "suite.md")
    print(text)


if __name__ == "__main__":
    main()
