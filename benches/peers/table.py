#!/usr/bin/env python3
"""Print the side-by-side table of one `benches/peers/run.sh` run from the files it left in OUT.

    table.py OUT

Files read (each optional; a missing one is a skipped peer): `{case}.strata.json` (`strata render
--stats-json`), `{case}.{strata,pov,mitsuba}.time` (process wall and CPU seconds, cputime.py),
`{case}.pov.log` (POV-Ray's statistics), `{case}.mitsuba.json` (mitsuba_scene.py), and
`{case}.quality.jsonl` (mitsuba_scene.py compare), `{case}.pov_diff.json`, `machine.txt`.

Columns: "render s" is each renderer's own render time (Strata: `seconds` of the stats, scene loading
excluded; POV-Ray: Trace Time; Mitsuba: the fastest warm `mi.render` call, JIT excluded); "CPU s" the
CPU seconds of that phase where the renderer exposes them (POV-Ray: its trace CPU-seconds; Mitsuba:
getrusage around the warm render) or of the whole process (Strata: parse + BVH + render + writing the
image; the first two take milliseconds here); "M rays / CPU s" x threads estimates the rate on
otherwise idle cores.
"""
import json
import os
import re
import sys

CASES = [
    ("glass_csg", "pov", "(a) glass + CSG + 8x8 area light, 2x2 AA, depth 6"),
    ("spheres_path", "mitsuba", "(b) 1000 spheres, path tracing, max depth 8 (Mitsuba) = 6 bounces (Strata)"),
    ("spheres_direct", "mitsuba", "(b') 1000 spheres, direct lighting, 1 light sample"),
]


def read(path):
    try:
        with open(path) as f:
            return f.read()
    except FileNotFoundError:
        return None


def parse_pov(log):
    """POV-Ray 3.7's render statistics: `Rays` counts camera, reflected, refracted and transmitted
    rays; shadow rays are counted separately as `Shadow Ray Tests`."""
    def num(pattern):
        m = re.search(pattern, log)
        return float(m.group(1)) if m else None
    trace = num(r"Trace Time:.*\(([\d.]+) seconds\)")
    rays = num(r"Rays:\s+(\d+)")
    shadow = num(r"Shadow Ray Tests:\s+(\d+)")
    samples = num(r"Samples:\s+(\d+)")
    if trace is None or rays is None or shadow is None:
        return None
    cpu = num(r"Trace Time:.*\n.*with ([\d.]+) CPU-seconds total")
    return {"seconds": trace, "cpu": cpu, "rays": rays + shadow, "camera_and_secondary": rays, "shadow": shadow,
            "samples": samples}


def fmt(x, nd=2):
    return "-" if x is None else f"{x:.{nd}f}"


def main():
    out = sys.argv[1]
    rows = []
    notes = []
    mse = {}  # (title, "Strata" | "Mitsuba") -> MSE against the reference
    for case, peer, title in CASES:
        s = read(os.path.join(out, f"{case}.strata.json"))
        if s is None:
            continue
        s = json.loads(s)
        s_time = read(os.path.join(out, f"{case}.strata.time"))
        s_time = json.loads(s_time) if s_time else {}
        strata = {"seconds": s["seconds"], "rays": s["rays"]["total"], "wall": s_time.get("wall"), "cpu": s_time.get("cpu")}
        cleared = s["rays"].get("shadow_cleared", 0)
        rows.append((title, "Strata", strata, f"own counters: camera {s['rays']['camera'] / 1e6:.2f}M, "
                     f"secondary {s['rays']['secondary'] / 1e6:.2f}M, shadow {s['rays']['shadow'] / 1e6:.2f}M"
                     + (f" traced (+ {cleared / 1e6:.2f}M light samples the light-cone test found clear, credited "
                        "untraced and not counted)" if cleared else "")))
        p_time = read(os.path.join(out, f"{case}.{peer}.time"))
        p_wall = json.loads(p_time)["wall"] if p_time else None
        if peer == "pov":
            log = read(os.path.join(out, f"{case}.pov.log"))
            p = parse_pov(log) if log else None
            if p:
                p["wall"] = p_wall
                rows.append((title, "POV-Ray 3.7", p, f"own counters: Rays {p['camera_and_secondary'] / 1e6:.2f}M "
                             f"(camera + reflected + refracted; {p['samples'] / 1e6:.2f}M AA samples) "
                             f"+ Shadow Ray Tests {p['shadow'] / 1e6:.2f}M"))
            else:
                rows.append((title, "POV-Ray 3.7", None, "skipped (see run log)"))
            diff = read(os.path.join(out, f"{case}.pov_diff.json"))
            if diff:
                d = json.loads(diff)
                notes.append(f"{title}: Strata vs POV-Ray PNGs differ by {d['mean_abs']:.2f} / 255 on average "
                             f"({d['over_16'] * 100:.1f}% of channel values by more than 16 / 255).")
        else:
            m = read(os.path.join(out, f"{case}.mitsuba.json"))
            if m:
                m = json.loads(m)
                mit = {"seconds": m["seconds"], "rays": m["rays_estimated"], "wall": p_wall, "cpu": m.get("cpu_seconds")}
                rows.append((title, f"Mitsuba {m['version']} {m['variant']}", mit,
                             f"estimated: {m['paths'] / 1e6:.1f}M paths x {m['rays_per_path']:.3f} rays/path "
                             f"({m['shadow_rays_per_path']:.3f} shadow) from a counting replay; "
                             f"first render (JIT) {m['first_render_seconds']:.2f} s, "
                             f"{m['paths_per_second'] / 1e6:.1f}M paths/s warm"))
            else:
                rows.append((title, "Mitsuba 3 llvm_ad_rgb", None, "skipped (see run log)"))
            q = read(os.path.join(out, f"{case}.quality.jsonl"))
            if q:
                for line in q.splitlines():
                    r = json.loads(line)
                    who = "Strata" if "strata" in os.path.basename(r["image"]) else "Mitsuba"
                    mse[(title, who)] = r["mse"]
                    notes.append(f"{title}: {who} MSE {r['mse']:.3e}, relMSE {r['relmse']:.3e} against a "
                                 f"{r.get('ref_spp', '?')} spp Mitsuba reference (image mean {r['mean']:.4f}, "
                                 f"reference mean {r['ref_mean']:.4f}).")

    print("| scene | renderer | render s | CPU s | process wall s | rays (M) | M rays/s | M rays / CPU s | "
          "Strata time / peer time | rays counted by |")
    print("|---|---|---:|---:|---:|---:|---:|---:|---:|---|")
    strata_time, strata_cpu = {}, {}
    for title, who, r, how in rows:
        if r is None:
            print(f"| {title} | {who} | - | - | - | - | - | - | - | {how} |")
            continue
        if who == "Strata":
            strata_time[title], strata_cpu[title] = r["seconds"], r.get("cpu")
            ratio = "1"
        else:
            ratio = fmt(strata_time[title] / r["seconds"], 3) if title in strata_time else "-"
            if strata_cpu.get(title) and r.get("cpu"):
                ratio += f" (CPU {strata_cpu[title] / r['cpu']:.3f})"
        cpu = r.get("cpu")
        per_cpu = fmt(r["rays"] / cpu / 1e6) if cpu else "-"
        print(f"| {title} | {who} | {fmt(r['seconds'])} | {fmt(cpu)} | {fmt(r['wall'])} | {fmt(r['rays'] / 1e6, 1)} | "
              f"{fmt(r['rays'] / r['seconds'] / 1e6)} | {per_cpu} | {ratio} | {how} |")
    for n in notes:
        print(f"\n- {n}")
    # Equal quality: MSE falls as 1/samples, so a renderer with MSE e in time t needs t e / e' for MSE e'.
    times = {(title, "Strata" if who == "Strata" else "Mitsuba"): r for title, who, r, _ in rows if r}
    for (title, who), _ in list(mse.items()):
        if who != "Strata" or (title, "Mitsuba") not in mse:
            continue
        s_r, m_r = times.get((title, "Strata")), times.get((title, "Mitsuba"))
        if not (s_r and m_r):
            continue
        ms, mm = mse[(title, "Strata")], mse[(title, "Mitsuba")]
        line = (f"{title}: at equal error (MSE proportional to 1 / samples) Strata needs "
                f"{s_r['seconds'] * ms / (m_r['seconds'] * mm):.2f}x Mitsuba's render time")
        if s_r.get("cpu") and m_r.get("cpu"):
            line += f" ({s_r['cpu'] * ms / (m_r['cpu'] * mm):.2f}x its CPU time)"
        print(f"\n- {line}.")
    m = read(os.path.join(out, "machine.txt"))
    if m:
        print("\n```\n" + m.strip() + "\n```")


if __name__ == "__main__":
    main()
