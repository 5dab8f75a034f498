#!/usr/bin/env python3
"""Summarises a scripts/soak.sh run: soak.json, soak.svg, and the checks.

Reads OUT/samples.txt (lines `ms process pid rss_kB cpu_ticks`), the agents'
logs in OUT/mission/logs, OUT/mission/report.json and, if the equality check
is on, OUT/vs-offline.json (lmf-score --json). Exits 1 if a check fails.
"""
import argparse
import json
import os
import re
import sys

GROWTH_LIMIT = 0.10   # RSS growth over the second half of the run
MIN_GROWTH_CHECK_S = 600
EQUAL_LIMIT_M = 0.01  # trajectories vs lmf-offline (the README's 1 mm claim, with margin)


def read_samples(path):
    series = {}
    if not os.path.exists(path):
        return series
    for n, line in enumerate(open(path), 1):
        parts = line.split()
        if len(parts) != 5:
            continue  # a line cut when the sampler was stopped
        try:
            ms, name, _pid, rss, ticks = int(parts[0]), parts[1], parts[2], int(parts[3]), int(parts[4])
        except ValueError:
            print(f"soak: {path}:{n}: malformed sample line, skipped", file=sys.stderr)
            continue
        series.setdefault(name, []).append((ms / 1000.0, rss, ticks))
    return series


def at(samples, t):
    """The last sample at or before time t (the first one if none)."""
    best = samples[0]
    for s in samples:
        if s[0] <= t:
            best = s
    return best


def process_summary(name, samples, ticks_per_s):
    t_start, t_end = samples[0][0], samples[-1][0]
    half = at(samples, t_start + (t_end - t_start) / 2)
    end = samples[-1]
    cpu_s = (end[2] - samples[0][2]) / ticks_per_s
    span = max(t_end - t_start, 1e-9)
    return {
        "samples": len(samples),
        "seconds": round(t_end - t_start, 1),
        "rss_start_mb": round(samples[0][1] / 1024, 1),
        "rss_half_mb": round(half[1] / 1024, 1),
        "rss_end_mb": round(end[1] / 1024, 1),
        "rss_max_mb": round(max(s[1] for s in samples) / 1024, 1),
        "rss_growth_second_half": round((end[1] - half[1]) / half[1], 4) if half[1] > 0 else None,
        "cpu_s": round(cpu_s, 1),
        "cpu_percent_mean": round(100.0 * cpu_s / span, 1),
    }


def agent_counts(logs_dir, robots):
    counts = {}
    pattern = re.compile(r"(\d+) local maps shipped, (\d+) acknowledged, (\d+) resends")
    for r in range(robots):
        path = os.path.join(logs_dir, f"agent{r}.log")
        found = None
        if os.path.exists(path):
            for line in open(path):
                m = pattern.search(line)
                if m:
                    found = {"shipped": int(m.group(1)), "acknowledged": int(m.group(2)), "resends": int(m.group(3))}
        counts[f"robot{r}"] = found
    return counts


def svg_plot(series, path, ticks_per_s):
    width, height, left, right, top, gap, panel = 900, 560, 70, 170, 30, 50, 220
    t_max = max((s[-1][0] for s in series.values() if s), default=1.0) or 1.0
    rss_max = max((x[1] for s in series.values() for x in s), default=1) / 1024 or 1.0
    colours = ["#1f77b4", "#d62728", "#2ca02c", "#9467bd", "#ff7f0e", "#8c564b", "#e377c2", "#7f7f7f",
               "#bcbd22", "#17becf", "#393b79", "#637939"]
    out = [f'<svg xmlns="http://www.w3.org/2000/svg" width="{width}" height="{height}" font-family="sans-serif" '
           f'font-size="12"><rect width="100%" height="100%" fill="white"/>']
    plot_w = width - left - right

    def panel_frame(y0, title, y_label_max, unit):
        out.append(f'<text x="{left}" y="{y0 - 8}" font-weight="bold">{title}</text>')
        out.append(f'<rect x="{left}" y="{y0}" width="{plot_w}" height="{panel}" fill="none" stroke="#888"/>')
        out.append(f'<text x="{left - 6}" y="{y0 + 10}" text-anchor="end">{y_label_max:.0f} {unit}</text>')
        out.append(f'<text x="{left - 6}" y="{y0 + panel}" text-anchor="end">0</text>')

    cpu = {}
    for name, s in series.items():
        pts = []
        for a, b in zip(s, s[1:]):
            dt = b[0] - a[0]
            if dt > 0:
                pts.append((b[0], 100.0 * (b[2] - a[2]) / ticks_per_s / dt))
        cpu[name] = pts
    cpu_max = max((p[1] for pts in cpu.values() for p in pts), default=100.0) or 100.0
    y_rss, y_cpu = top + 10, top + 10 + panel + gap
    panel_frame(y_rss, "resident memory (RSS)", rss_max, "MB")
    panel_frame(y_cpu, "CPU (one core = 100 %)", cpu_max, "%")
    for k, name in enumerate(sorted(series)):
        colour = colours[k % len(colours)]
        s = series[name]
        rss_pts = " ".join(f"{left + plot_w * t / t_max:.1f},{y_rss + panel * (1 - r / 1024 / rss_max):.1f}"
                           for t, r, _ in s)
        cpu_pts = " ".join(f"{left + plot_w * t / t_max:.1f},{y_cpu + panel * (1 - c / cpu_max):.1f}"
                           for t, c in cpu[name])
        out.append(f'<polyline fill="none" stroke="{colour}" stroke-width="1.5" points="{rss_pts}"/>')
        if cpu_pts:
            out.append(f'<polyline fill="none" stroke="{colour}" stroke-width="1" points="{cpu_pts}"/>')
        out.append(f'<text x="{width - right + 10}" y="{y_rss + 14 * k + 10}" fill="{colour}">{name}</text>')
    out.append(f'<text x="{left + plot_w}" y="{height - 8}" text-anchor="end">{t_max:.0f} s</text>')
    out.append(f'<text x="{left}" y="{height - 8}">0 s</text>')
    out.append("</svg>")
    with open(path, "w") as f:
        f.write("\n".join(out) + "\n")


def main():
    p = argparse.ArgumentParser()
    p.add_argument("--out", required=True)
    p.add_argument("--robots", type=int, required=True)
    p.add_argument("--duration-s", type=float, required=True)
    p.add_argument("--wall-s", type=float, required=True)
    p.add_argument("--mode", required=True)
    p.add_argument("--loss", type=float, default=0.0)
    p.add_argument("--equal-check", type=int, default=0)
    p.add_argument("--clock-ticks", type=float, default=100.0)
    a = p.parse_args()

    series = read_samples(os.path.join(a.out, "samples.txt"))
    failures = []
    processes = {name: process_summary(name, s, a.clock_ticks) for name, s in sorted(series.items()) if s}
    if not processes:
        failures.append("no memory samples were taken")
    growth_checked = a.duration_s >= MIN_GROWTH_CHECK_S
    for name, s in processes.items():
        g = s["rss_growth_second_half"]
        if growth_checked and name != "lmf-player" and g is not None and g >= GROWTH_LIMIT:
            failures.append(f"{name}: RSS grew {100 * g:.1f} % over the second half (limit {100 * GROWTH_LIMIT:.0f} %)")

    agents = agent_counts(os.path.join(a.out, "mission", "logs"), a.robots)
    shipped = acknowledged = resends = 0
    for robot, c in agents.items():
        if c is None:
            failures.append(f"{robot}: its agent did not report its local maps (logs/{robot.replace('robot', 'agent')}.log)")
            continue
        shipped += c["shipped"]
        acknowledged += c["acknowledged"]
        resends += c["resends"]
        if c["acknowledged"] != c["shipped"]:
            failures.append(f"{robot}: {c['acknowledged']} of {c['shipped']} local maps acknowledged")

    report_path = os.path.join(a.out, "mission", "report.json")
    fusions = None
    if os.path.exists(report_path):
        report = json.load(open(report_path))
        fusions = len(report.get("fusions", [])) if isinstance(report.get("fusions"), list) else None
    vs_offline = None
    if a.equal_check:
        try:
            vs_offline = json.load(open(os.path.join(a.out, "vs-offline.json")))["ate_position_rmse_m"]
            if vs_offline >= EQUAL_LIMIT_M:
                failures.append(f"trajectories differ from lmf-offline by {vs_offline} m RMS")
        except (OSError, ValueError, KeyError) as e:
            failures.append(f"no comparison with lmf-offline ({e})")

    summary = {
        "robots": a.robots, "mission_s": a.duration_s, "player": a.mode, "loss": a.loss, "wall_s": a.wall_s,
        "local_maps_shipped": shipped, "local_maps_acknowledged": acknowledged, "local_map_resends": resends,
        "fusions_in_report": fusions, "agents": agents,
        "trajectories_vs_offline_rmse_m": vs_offline,
        "memory_growth_checked": growth_checked, "processes": processes,
        "failures": failures, "passed": not failures,
    }
    with open(os.path.join(a.out, "soak.json"), "w") as f:
        json.dump(summary, f, indent=2)
    svg_plot(series, os.path.join(a.out, "soak.svg"), a.clock_ticks)

    print(f"soak: {a.robots} robots, {a.duration_s:.0f} s mission, player {a.mode}, loss {a.loss}: {a.wall_s:.0f} s wall")
    print(f"soak: local maps shipped {shipped}, acknowledged {acknowledged}, resends {resends}"
          + (f"; trajectories vs lmf-offline {vs_offline:.2e} m RMS" if vs_offline is not None else ""))
    for name, s in processes.items():
        g = s["rss_growth_second_half"]
        print(f"soak: {name:14s} RSS {s['rss_start_mb']:7.1f} -> {s['rss_end_mb']:7.1f} MB (max {s['rss_max_mb']:.1f}, "
              f"second half {'' if g is None else f'{100 * g:+.1f} %'}), CPU {s['cpu_s']:.1f} s "
              f"({s['cpu_percent_mean']:.0f} % mean)")
    if not growth_checked:
        print(f"soak: memory growth reported, not checked (missions under {MIN_GROWTH_CHECK_S} s)")
    print(f"soak: wrote {os.path.join(a.out, 'soak.json')} and soak.svg")
    for f in failures:
        print(f"soak: FAIL: {f}")
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
