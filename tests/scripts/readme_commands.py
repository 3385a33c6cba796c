#!/usr/bin/env python3
"""readme_commands.py SOURCE_DIR BUILD_DIR TMP - every command README.md shows, run where cheap.

Runs `prodygs COMMAND --help` for every command `prodygs --help` lists (and checks that README's
command table names each one), then each line of README's ```sh blocks and each ```python block
in a scratch folder TMP that looks like a checkout (build/, python/, scripts/, docs/ linked in)
and holds the files the examples name: my.mp4 (a 6-frame 96x72 clip of the sample scene),
depth.npy and disparity.npy of it, and model.tflite (a copy of the built-in network). `run` and
`eval` get `--iters 30 --proxies 2` added, the Python example's `iters` is cut to 30; nothing
else is changed. Lines that other tests run are named with the test that runs them.
"""
import os
import re
import shutil
import subprocess
import sys

src, build, tmp = (os.path.abspath(a) for a in sys.argv[1:4])
cli = os.path.join(build, "prodygs")
ELSEWHERE = {  # first word(s) -> the test that runs it
    "./scripts/run-demo": "CI's own run (.ci/run -> scripts/run-tests; the demo is test_stage_api's pipeline)",
    "./scripts/run-tests": "CI (.ci/run)",
    "cmake --install": "install_pkgconfig",
    "cc docs/example_pipeline.c": "install_pkgconfig",
    "scripts/slurm-array": "slurm_array",
    "scripts/gather-runs": "slurm_array",
}
failed = []


def sh(cmd, **kw):
    print("$ " + cmd, flush=True)
    r = subprocess.run(cmd, shell=True, cwd=tmp, capture_output=True, text=True, **kw)
    if r.returncode != 0:
        print(r.stdout[-2000:] + r.stderr[-3000:])
        failed.append(cmd)
    return r


readme = open(os.path.join(src, "README.md")).read()

# 1. every command's --help, and the table lists every command
top = subprocess.run([cli, "--help"], capture_output=True, text=True, check=True).stdout
commands = re.findall(r"^  (\w+)\s{2,}", top.split("commands:", 1)[1], re.M)
for c in commands:
    r = subprocess.run([cli, c, "--help"], capture_output=True, text=True)
    if r.returncode != 0 or "usage: prodygs " + c not in r.stdout:
        failed.append("prodygs %s --help" % c)
    if not re.search(r"^\| `prodygs %s[ `]" % c, readme, re.M):
        failed.append("README's command table has no row for %s" % c)
print("%d commands: --help of each, and each in README's table" % len(commands))

# 2. the scratch checkout and the files the examples name
shutil.rmtree(tmp, ignore_errors=True)
os.makedirs(tmp)
for d in ("python", "scripts", "docs", "include"):
    os.symlink(os.path.join(src, d), os.path.join(tmp, d))
os.symlink(build, os.path.join(tmp, "build"))
shutil.copy(os.path.join(src, "README.md"), os.path.join(tmp, "README.md"))
env = dict(os.environ, XDG_CACHE_HOME=os.path.join(tmp, "cache"), OMP_WAIT_POLICY="PASSIVE",
           PRODYGS_LIB=os.path.join(build, "libprodygs.so.0"), PYTHONDONTWRITEBYTECODE="1")
os.environ.update(env)
subprocess.run([cli, "synth", os.path.join(tmp, "clip"), "--cams", "1", "--frames", "6", "--size", "96x72", "--video",
                "--threads", "2"], check=True, capture_output=True)
shutil.copy(os.path.join(tmp, "clip", "cam00.mp4"), os.path.join(tmp, "my.mp4"))
shutil.copy(os.path.join(tmp, "clip", "depth_mono", "cam00.npy"), os.path.join(tmp, "depth.npy"))
subprocess.run(["/usr/bin/python3", "-c", "import numpy as np; d = np.load('depth.npy').astype('f4'); "
                "np.save('disparity.npy', 1 / d)"], cwd=tmp, check=True)
subprocess.run([cli, "depth", "my.mp4", "--out", "warm.npy", "--frames", "1"], cwd=tmp, check=True, capture_output=True)
model = os.path.join(tmp, "cache", "prodygs", "fastdepth_224_int8.tflite")
shutil.copy(model, os.path.join(tmp, "model.tflite"))
shutil.copy(model + ".json", os.path.join(tmp, "model.tflite.json"))

# 3. README's shell lines, in order, and its Python blocks
ran = 0
for block in re.findall(r"```sh\n(.*?)```", readme, re.S):
    for line in block.splitlines():
        cmd = re.sub(r"\s+#\s.*$", "", line).strip()
        if not cmd:
            continue
        where = next((t for k, t in ELSEWHERE.items() if cmd.startswith(k)), None)
        if where:
            print("- %s   (run by %s)" % (cmd, where))
            continue
        if re.match(r"build/prodygs (run|eval) ", cmd) and "--iters" not in cmd:
            cmd += " --iters 30 --proxies 2"
        sh(cmd)
        ran += 1
for block in re.findall(r"```python\n(.*?)```", readme, re.S):
    code = re.sub(r"iters=\d+", "iters=30", block)
    print(">>> python:\n" + code, flush=True)
    r = subprocess.run(["/usr/bin/python3", "-c", "import sys; sys.path.insert(0, 'python')\n" + code], cwd=tmp,
                       capture_output=True, text=True)
    print(r.stdout[-1500:])
    if r.returncode != 0:
        print(r.stderr[-3000:])
        failed.append("python block: " + block.splitlines()[0])
    ran += 1

# the results table's script: prints the table and rewrites the block of (a copy of) README.md
r = sh("scripts/results-table --write README.md")
copy = open(os.path.join(tmp, "README.md")).read()
block = copy.split("<!-- results-table:begin -->", 1)[1].split("<!-- results-table:end -->", 1)[0]
rows = [l for l in block.splitlines() if l.startswith("| ") and not l.startswith("| data ")]
if len(rows) != len(__import__("json").load(open(os.path.join(src, "scripts", "results.json")))["runs"]):
    failed.append("results-table wrote %d rows" % len(rows))
if any(len(cell) > 300 for l in rows for cell in l.split("|")):
    failed.append("results-table: a cell over 300 characters")
for line in readme.splitlines():
    if line.startswith("|") and any(len(cell) > 300 for cell in line.split("|")):
        failed.append("README table cell over 300 characters: " + line[:60])
if len(readme.splitlines()) > 260:
    failed.append("README.md has %d lines" % len(readme.splitlines()))

# a few of the results the examples promise
for path in ("out/report.md", "out/renders/orbit.mp4", "out/bullet", "out/ply", "out/viewer/index.html", "ev/metrics.json",
             "depth.npy", "out_disp/report.md", "out_model/report.md"):
    if not os.path.exists(os.path.join(tmp, path)):
        failed.append("missing after the examples: " + path)
if failed:
    print("readme_commands: FAILED:\n  " + "\n  ".join(failed))
    sys.exit(1)
print("readme_commands: ok (%d commands and blocks run, %d --help)" % (ran, len(commands)))
shutil.rmtree(tmp, ignore_errors=True)
