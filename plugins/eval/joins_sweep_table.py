#!/usr/bin/env python3
"""Markdown table of a lidar_sweep workspace: one row per seed from joins/summary.json and
joins/joins_eval.csv (per-sequence drift, RPE, scale, heading bias). Usage: plugins/eval/joins_sweep_table.py WORKSPACE [LOCFORGE_BINARY]"""
import csv, io, subprocess, sys
w = sys.argv[1]
lf = sys.argv[2] if len(sys.argv) > 2 else "locforge"
def collect(f):
    out = subprocess.run([lf, 'collect', w, f], capture_output=True, text=True, check=True).stdout
    return list(csv.DictReader(io.StringIO(out)))
summ = {r['variant']: r for r in collect('joins/summary.json')}
seqs = {}
for r in collect('joins/joins_eval.csv'):
    seqs.setdefault(r['variant'], []).append(r)
print('| seed | right / wrong / refused | fully joined | ATE whole (cm RMS / max) | rotation whole (deg RMS) | own ATE per sequence (cm, worst) | RPE 1 m (cm, worst) | scale (worst) | heading bias (deg, worst) |')
print('|---|---|---|---|---|---|---|---|---|')
tot = [0, 0, 0, 0]
for v in sorted(summ, key=lambda x: int(x.split('=')[1])):
    s = summ[v]; q = [r for r in seqs.get(v, []) if r['status'] != 'separate']
    tot[0] += int(s['right']); tot[1] += int(s['wrong']); tot[2] += int(s['refused']); tot[3] += s['fully_joined'] == 'true'
    own = max(float(r['ate_own_m']) for r in q) * 100
    rpe = max(float(r['rpe_1m_m']) for r in q) * 100
    sc = max(q, key=lambda r: abs(float(r['scale']) - 1))['scale']
    hb = max(q, key=lambda r: abs(float(r['yaw_bias_deg'])))['yaw_bias_deg']
    print(f"| {v.split('=')[1]} | {s['right']} / {s['wrong']} / {s['refused']} | {'yes' if s['fully_joined']=='true' else 'no'} | "
          f"{float(s['ate_whole_m'])*100:.2f} / {float(s['ate_whole_max_m'])*100:.2f} | {float(s['rotation_whole_deg']):.3f} | "
          f"{own:.2f} | {rpe:.2f} | {float(sc):.4f} | {float(hb):+.3f} |")
print(f"| **all {len(summ)}** | **{tot[0]} / {tot[1]} / {tot[2]}** | **{tot[3]} of {len(summ)}** | | | | | | |")
