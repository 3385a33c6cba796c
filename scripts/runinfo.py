"""runinfo.py - what a `prodygs run` / `prodygs eval` output folder says about its run.

Read by scripts/gather-runs (the Slurm summary) and scripts/results-table (README's results).
Only the files the pipeline writes are read: the stage markers (DIR/<stage>.done), DIR/report.md
and, when test cameras were scored, DIR/metrics.json. Standard library only.
"""
import json
import math
import os
import re

STAGES = ("depth", "prepare", "proxies", "train", "evaluate", "render")


def _num(pattern, text):
    m = re.search(pattern, text)
    return float(m.group(1).replace(",", "")) if m else None


def _finite(v):
    return v if isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v) else None


def read_run(path):
    """A dict of what is known about the run in folder path (values None when unknown):
    state ("done", "running or cut off after STAGE", "not started"), stages_done, command,
    train_psnr / train_psnr_moving / train_psnr_static (the model at its own camera, report.md),
    psnr / ssim / psnr_moving (held-out cameras, metrics.json), baseline_psnr (a flat-image
    baseline, when metrics.json carries one), seconds, peak_mib, frames, gaussians."""
    r = {k: None for k in ("command", "train_psnr", "train_psnr_moving", "train_psnr_static", "psnr", "ssim",
                           "psnr_moving", "baseline_psnr", "seconds", "peak_mib", "frames", "gaussians")}
    r["path"] = path
    r["stages_done"] = [s for s in STAGES if os.path.exists(os.path.join(path, s + ".done"))]
    report = os.path.join(path, "report.md")
    text = ""
    if os.path.isfile(report):
        with open(report, encoding="utf-8", errors="replace") as f:
            text = f.read()
        m = re.search(r"```\n((?:prodygs |python3: )[^\n]*)\n```", text)
        r["command"] = m.group(1) if m else None
        r["peak_mib"] = _num(r"Peak memory ([\d.,]+) MiB", text)
        r["seconds"] = _num(r"Total ([\d.,]+) s", text)
        r["train_psnr"] = _num(r"training camera against the input frames(?: at [^:]*)?: PSNR ([\d.]+) dB", text)
        r["train_psnr_moving"] = _num(r"moving pixels ([\d.]+) dB", text)
        r["train_psnr_static"] = _num(r"static pixels ([\d.]+) dB", text)
        r["gaussians"] = _num(r"iterations, ([\d,]+) Gaussians", text)
        # the stage table: each stage's own seconds and peak, also for stages an earlier
        # invocation ran (a resumed run's "Total" is only the last invocation's)
        m = re.search(r"^\| stage \| seconds \|([^\n]*)\n\|[-|]+\n((?:\|[^\n]*\n)+)", text, re.M)
        if m:
            cols = ["stage", "seconds"] + [c.strip() for c in m.group(1).split("|")]
            secs, peaks = [], []
            for line in m.group(2).splitlines():
                cells = [c.strip() for c in line.strip().strip("|").split("|")]
                row = dict(zip(cols, cells))
                try:
                    secs.append(float(row["seconds"]))
                    if row.get("peak memory MiB"):
                        peaks.append(float(row["peak memory MiB"]))
                except ValueError:
                    pass
            if secs:
                r["seconds"] = sum(secs)
            if peaks:
                r["peak_mib"] = max(peaks + [r["peak_mib"] or 0])
    metrics = os.path.join(path, "metrics.json")
    if os.path.isfile(metrics):
        with open(metrics) as f:
            m = json.load(f)
        r["psnr"], r["ssim"], r["frames"] = _finite(m.get("psnr")), _finite(m.get("ssim")), m.get("frames")
        r["psnr_moving"] = _finite(m.get("regions", {}).get("moving", {}).get("psnr"))
        tc = m.get("train_camera", {})
        if isinstance(tc, dict):
            r["train_psnr"] = r["train_psnr"] or _finite(tc.get("psnr"))
            reg = tc.get("regions", {})
            r["train_psnr_moving"] = r["train_psnr_moving"] or _finite(reg.get("moving", {}).get("psnr"))
            r["train_psnr_static"] = r["train_psnr_static"] or _finite(reg.get("static", {}).get("psnr"))
        flat = (m.get("baselines") or {}).get("flat")  # eval's yardsticks (docs/eval.md)
        if isinstance(flat, dict) and _finite(flat.get("psnr")) is not None:
            r["baseline_psnr"] = flat["psnr"]
        cfg = m.get("config", {})
        r["command"] = r["command"] or cfg.get("command")
        stages = m.get("stages", {})
        if isinstance(stages, dict) and stages:
            secs = [_finite(s.get("seconds")) for s in stages.values() if isinstance(s, dict)]
            peaks = [_finite(s.get("peak_mib")) for s in stages.values() if isinstance(s, dict)]
            if r["seconds"] is None and any(v is not None for v in secs):
                r["seconds"] = sum(v for v in secs if v is not None)
            if r["peak_mib"] is None and any(v is not None for v in peaks):
                r["peak_mib"] = max(v for v in peaks if v is not None)
    finished = text and "train" in r["stages_done"]
    if finished:
        r["state"] = "done"
    elif r["stages_done"]:
        r["state"] = "cut off after " + r["stages_done"][-1]
    elif os.path.isdir(path):
        r["state"] = "started"
    else:
        r["state"] = "not started"
    return r


def fmt(v, digits=2):
    """A table cell: '-' for unknown, numbers with the given decimals."""
    if v is None:
        return "-"
    if isinstance(v, float):
        return "%.*f" % (digits, v)
    return str(v)


def fmt_time(seconds):
    if seconds is None:
        return "-"
    s = int(round(seconds))
    return "%d:%02d" % (s // 60, s % 60) if s >= 60 else "%.1f s" % seconds
