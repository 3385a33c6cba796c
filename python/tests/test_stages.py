"""The Python module's stages on a small sample scene, in this process through libprodygs.so.

    PRODYGS_CLI=build/prodygs python3 python/tests/test_stages.py [TMPDIR]

Makes the sample scene with `prodygs synth` (3 cameras, 6 frames, 96x72, with cam00.mp4), then:
depth of the video from the built-in network (numpy out), prepare from a numpy depth array,
proxies, train, render, export, the web viewer, the whole pipeline with a held-out camera, a
rerun that skips every stage, evaluate, and errors as prodygs.Error with pg_last_error().
Exits 77 (skipped) when numpy is not installed.
"""
import json
import math
import os
import shutil
import subprocess
import sys
import tempfile

here = os.path.dirname(os.path.abspath(__file__))
try:
    import numpy as np
except ImportError:
    print("test_stages: SKIP: numpy is not installed (apt-get install python3-numpy)")
    sys.exit(77)
sys.path.insert(0, os.path.join(here, ".."))
import prodygs  # noqa: E402

FAST = dict(iters=30, threads=2)


def check(cond, what):
    if not cond:
        raise AssertionError(what)
    print("ok   " + what)


def main():
    cli = os.environ.get("PRODYGS_CLI", os.path.join(here, "..", "..", "build", "prodygs"))
    top = sys.argv[1] if len(sys.argv) > 1 else tempfile.mkdtemp(prefix="prodygs-py-")
    shutil.rmtree(top, ignore_errors=True)
    os.makedirs(top)
    print("library %s, version %s" % (prodygs.library_path, prodygs.version()))
    data = os.path.join(top, "s1")
    subprocess.run([cli, "synth", data, "--cams", "3", "--frames", "6", "--size", "96x72", "--video",
                    "--threads", "2"], check=True, stdout=subprocess.DEVNULL)
    video = os.path.join(data, "cam00.mp4")
    mono = prodygs.load_depth(os.path.join(data, "depth_mono", "cam00.npy"))
    check(mono.shape == (6, 72, 96) and mono.dtype == np.float32, "load_depth: %s %s" % (mono.shape, mono.dtype))

    # depth: the built-in FastDepth on the video, a numpy array back
    d, rep = prodygs.depth(video, frames=2, threads=2, return_report=True)
    check(d.ndim == 3 and d.shape[0] == 2 and np.isfinite(d).all() and (d > 0).mean() > 0.9,
          "depth: built-in network, array %s, model %s" % (d.shape, rep["model_name"]))

    # prepare from a numpy array; its output read back as an array
    prep = os.path.join(top, "prepare")
    rep = prodygs.prepare(video, prep, depth=mono, threads=2)
    aligned = prodygs.load_depth(rep["depth_aligned"])
    check(rep["frames"] == 6 and aligned.shape == (6, rep["height"], rep["width"]),
          "prepare: %d frames %dx%d, residual %.4f -> %.4f" % (rep["frames"], rep["width"], rep["height"],
                                                               rep["residual_before"], rep["residual_after"]))

    prox = os.path.join(top, "proxies")
    rep = prodygs.proxies(video, rep["depth_aligned"], prox, proxies=2, threads=2)
    check(rep["proxies"] == 2 and os.path.isdir(prox), "proxies: %d proxy cameras" % rep["proxies"])

    model = os.path.join(top, "model")
    rep = prodygs.train(prox, model, **FAST)
    check(rep["iterations"] == 30 and rep["gaussians"] > 0 and rep["finished"] == 1,
          "train: %d iterations, %d Gaussians" % (rep["iterations"], rep["gaussians"]))

    rep = prodygs.render(model, os.path.join(top, "renders"), path="orbit", steps=4, threads=2)
    check(rep["frames"] == 4, "render: %d orbit frames" % rep["frames"])

    rep = prodygs.export(model, os.path.join(top, "ply"), times=[0.0, 0.5])
    plys = sorted(f for f in os.listdir(os.path.join(top, "ply")) if f.endswith(".ply"))
    check(rep["files"] == 2 and len(plys) == 2, "export: %d PLY files (%s)" % (rep["files"], ", ".join(plys)))

    rep = prodygs.view(model)
    check(os.path.isfile(os.path.join(model, "viewer", "scene.pgvs")), "view: %d frames" % rep["frames"])

    # the whole pipeline on the dataset with a held-out camera, then a rerun that skips every stage
    run = os.path.join(top, "run")
    opts = dict(depth=os.path.join(data, "depth_mono", "cam00.npy"), test_cameras="cam02", proxies=2, evaluate=1,
                render_videos=0, **FAST)
    rep = prodygs.run(data, run, **opts)
    ran = [s for s, v in rep["stages"].items() if v["ran"]]
    metrics = json.load(open(os.path.join(run, "metrics.json")))
    check(ran == ["prepare", "proxies", "train", "evaluate"] and math.isfinite(rep["evaluation"]["psnr"])
          and abs(metrics["psnr"] - rep["evaluation"]["psnr"]) < 1e-3,
          "run: stages %s, held-out PSNR %.2f dB, peak %d kB" % (",".join(ran), rep["evaluation"]["psnr"],
                                                                 rep["peak_rss_kb"]))
    rep = prodygs.run(data, run, **opts)
    ran = [s for s, v in rep["stages"].items() if v["ran"]]
    check(ran == ["evaluate"] or ran == [], "run again: every stage but scoring skipped (ran: %s)" % (ran,))

    rep = prodygs.evaluate(data, os.path.join(run, "model"), os.path.join(top, "eval"), threads=2)
    check(rep["frames"] == 6 and abs(rep["psnr"] - metrics["psnr"]) < 1e-3,
          "evaluate: %d frames, PSNR %.2f SSIM %.3f" % (rep["frames"], rep["psnr"], rep["ssim"]))

    # errors: an exception with the library's message; bad options are TypeErrors
    try:
        prodygs.train(os.path.join(top, "no_such_set"), os.path.join(top, "m2"), iters=5)
        raise AssertionError("train on a missing folder did not fail")
    except prodygs.Error as e:
        check(e.code == "arg" and e.status == 1 and "no_such_set" in str(e), "error: %s (%s)" % (e, e.reason))
    try:
        prodygs.train(prox, model, iterations=5)
        raise AssertionError("an unknown option was accepted")
    except TypeError as e:
        check("iterations" in str(e), "unknown option: TypeError")
    warnings = []
    prodygs.set_warning_handler(warnings.append)
    prodygs.prepare(video, os.path.join(top, "prepare_inverted"), depth=1.0 / mono, threads=2)  # disparity given as depth
    prodygs.set_warning_handler(None)
    check(any("disparity" in w for w in warnings), "warnings reach Python: %s" % warnings[:1])
    shutil.rmtree(top, ignore_errors=True)
    print("test_stages: ok")
    return 0


if __name__ == "__main__":
    sys.exit(main())
