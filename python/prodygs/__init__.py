"""prodygs - the ProDyGS pipeline (4D Gaussian splatting from one static-camera video) from Python.

Each stage of include/prodygs.h is one function that takes paths and the stage's options as
keyword arguments named like the fields of its C config (start values: the C _defaults), runs in
this process through libprodygs.so (ctypes; nothing is compiled at import) and returns its report
as a dict. A failure raises prodygs.Error carrying pg_last_error()'s message.

    import prodygs
    rep = prodygs.run("clip.mp4", "out")                   # the whole pipeline (`prodygs run`)
    d = prodygs.depth("clip.mp4")                          # (F, H, W) float32 numpy array
    rep = prodygs.prepare("clip.mp4", "out/prepare", depth=d)
    rep = prodygs.proxies("clip.mp4", "out/prepare/depth_aligned.npy", "out/proxies")
    rep = prodygs.train("out/proxies", "out/model", iters=300)
    rep = prodygs.render("out/model", "out/renders", path="orbit")

Depth can be given as a path (.npy or a folder) or as a numpy array of shape (F, H, W) (written
to a temporary .npy for the call); load_depth / save_depth read and write depth files.
"""
import ctypes as C
import math
import os
import tempfile

from . import _lib
from . import _types

__all__ = ["Error", "version", "library_path", "defaults", "depth", "prepare", "proxies", "train",
           "evaluate", "render", "export", "view", "run", "pipeline", "load_depth", "save_depth",
           "set_warning_handler", "default_depth_model", "STATUS"]

library_path = _lib.path
STATUS = ("ok", "arg", "io", "format", "size", "nomem", "internal", "env")  # pg_status, in order


class Error(Exception):
    """A stage failed. str(error) is pg_last_error()'s one line (naming the file or value at
    fault); .status is the pg_status number, .code its short name ("arg", "io", "format", "size",
    "nomem", "internal", "env"; STATUS), .reason pg_status_name's words and .stage the function."""

    def __init__(self, stage, status, message):
        self.stage = stage
        self.status = status
        self.code = STATUS[status] if 0 <= status < len(STATUS) else str(status)
        self.reason = _lib.status_name(status).decode()
        self.message = message
        super().__init__(message)


def version():
    """The loaded library's version (PRODYGS_VERSION)."""
    return _lib.version().decode()


_warning_keep = None


def set_warning_handler(fn):
    """Calls fn(message) for each warning the library gives (depth that looks like disparity, a
    stretching size, ...) instead of printing it on stderr; None restores the default."""
    global _warning_keep
    if fn is None:
        _warning_keep = None
        _lib.set_warning_handler(_lib.WARNING_HANDLER(), None)
        return
    _warning_keep = _lib.WARNING_HANDLER(lambda msg, ctx: fn(msg.decode(errors="replace")))
    _lib.set_warning_handler(_warning_keep, None)


def _encode(v):
    if isinstance(v, bytes):
        return v
    return os.fsencode(os.fspath(v))


def _config(stage, options):
    defaults_fn, _, cfg_t, _ = _lib.STAGES[stage]
    cfg = cfg_t()
    defaults_fn(C.byref(cfg))
    fields = dict(cfg_t._fields_)
    keep = []
    for key, value in options.items():
        if value is None:
            continue
        if key not in fields or key in ("on_plan", "user"):
            raise TypeError("prodygs.%s: unknown option %r (options: %s)"
                            % (stage, key, ", ".join(f for f in fields if f not in ("on_plan", "user"))))
        ftype = fields[key]
        if ftype is C.c_char_p:
            value = _encode(value)
        elif ftype in (C.c_int, C.c_long):
            if isinstance(value, float) and not value.is_integer():
                raise TypeError("prodygs.%s: option %s wants an integer, got %r" % (stage, key, value))
            value = int(value)
        elif ftype in (C.c_float, C.c_double):
            value = float(value)
        else:
            raise TypeError("prodygs.%s: option %s cannot be set from Python" % (stage, key))
        setattr(cfg, key, value)
        keep.append(value)
    return cfg, keep


def _value(v):
    if isinstance(v, bytes):
        return v.decode(errors="replace")
    if isinstance(v, C.Structure):
        return _report(v)
    if isinstance(v, C.Array):
        if v._type_ is C.c_char:
            return v.value.decode(errors="replace")
        return [_value(x) for x in v]
    return v


def _report(rep):
    return {name: _value(getattr(rep, name)) for name, _ in rep._fields_}


def _call(stage, cfg):
    _, run_fn, _, rep_t = _lib.STAGES[stage]
    rep = rep_t()
    status = run_fn(C.byref(cfg), C.byref(rep))
    if status != 0:
        msg = _lib.last_error()
        raise Error(stage, status, msg.decode(errors="replace") if msg else "failed")
    return _report(rep)


def default_depth_model():
    """The path of the built-in depth network (FastDepth, MIT), written into the user's cache
    folder on first use: what depth, prepare and run use when given no depth and no model."""
    buf = C.create_string_buffer(4096)
    status = _lib.default_model(buf, len(buf))
    if status != 0:
        raise Error("default_depth_model", status, _lib.last_error().decode(errors="replace"))
    return buf.value.decode()


def defaults(stage):
    """The C defaults of a stage's config as a dict ("depth", "prepare", ..., "pipeline")."""
    cfg, _ = _config(stage, {})
    return {k: v for k, v in _report(cfg).items() if k not in ("on_plan", "user")}


class _DepthArg:
    """A depth option that may be a numpy array: written to a temporary .npy for the call."""

    def __init__(self, value):
        self.value = value
        self.dir = None

    def __enter__(self):
        v = self.value
        if v is None or isinstance(v, (str, bytes, os.PathLike)):
            return v
        self.dir = tempfile.TemporaryDirectory(prefix="prodygs-depth-")
        path = os.path.join(self.dir.name, "depth.npy")
        save_depth(path, v)
        return path

    def __exit__(self, *exc):
        if self.dir is not None:
            self.dir.cleanup()
        return False


def _numpy():
    try:
        import numpy
    except ImportError as e:  # the stages themselves need no numpy; the array helpers do
        raise ImportError("prodygs: numpy is needed for depth arrays (apt-get install python3-numpy)") from e
    return numpy


def load_depth(path):
    """An (F, H, W) depth file (.npy, float16 or float32, as `prodygs depth` and prepare write
    them) as a float32 numpy array."""
    np = _numpy()
    return np.load(os.fspath(path), allow_pickle=False).astype(np.float32, copy=False)


def save_depth(path, depth):
    """Writes depth, an array of shape (F, H, W) (or (H, W): one frame), as a float32 .npy that
    every stage reads. Larger values are farther."""
    np = _numpy()
    a = np.asarray(depth, dtype=np.float32)
    if a.ndim == 2:
        a = a[None]
    if a.ndim != 3:
        raise ValueError("prodygs: depth must be (F, H, W) or (H, W), got shape %s" % (a.shape,))
    np.save(os.fspath(path), np.ascontiguousarray(a), allow_pickle=False)


def depth(input, out=None, model=None, **options):
    """Per-frame depth of a video, frame folder or dataset camera from a depth network (TFLite or
    ONNX; None: the built-in FastDepth), as a float32 numpy array (F, H, W). With out, the .npy is
    kept there (with its .json sidecar) and a rerun with the same settings reuses it. Options:
    the fields of pg_depth_config (train_camera, kind, size, out_width, out_height, frames,
    threads). return_report=True returns (array, report)."""
    return_report = options.pop("return_report", False)
    tmp = None
    if out is None:
        tmp = tempfile.TemporaryDirectory(prefix="prodygs-depth-")
        out = os.path.join(tmp.name, "depth.npy")
    try:
        if model is None:
            model = default_depth_model()
        cfg, keep = _config("depth", dict(options, input=input, out=out, model=model))
        rep = _call("depth", cfg)
        arr = load_depth(out)
    finally:
        if tmp is not None:
            tmp.cleanup()
    return (arr, rep) if return_report else arr


def prepare(input, out, depth=None, depth_model=None, **options):
    """Refines and temporally aligns per-frame depth (paper 3.1). depth: a path or an (F, H, W)
    array; neither depth nor depth_model: the built-in network. Writes OUT/depth_aligned.npy
    (load_depth reads it back; its path is the report's "depth_aligned"). Options: the fields of
    pg_prepare_config (depth_kind, depth_scale, refine, align, fuse, planes, movers_front,
    frames, width, height, threads, ...)."""
    if depth is None and depth_model is None:
        depth_model = default_depth_model()
    with _DepthArg(depth) as d:
        cfg, keep = _config("prepare", dict(options, input=input, out=out, depth=d, depth_model=depth_model))
        rep = _call("prepare", cfg)
    rep["depth_aligned"] = os.path.join(os.fspath(out), "depth_aligned.npy")
    return rep


def proxies(input, depth, out, **options):
    """Renders proxy views from virtual cameras (paper 3.2) into a training set OUT. depth:
    prepare's depth_aligned.npy (a path or an array). Options: the fields of pg_proxies_config
    (poses, proxies, max_angle, fov, pad, render, test_cameras, frames, threads, ...)."""
    with _DepthArg(depth) as d:
        cfg, keep = _config("proxies", dict(options, input=input, depth=d, out=out))
        return _call("proxies", cfg)


def train(input, out, **options):
    """Trains canonical Gaussians + the deformation network (paper 3.3) on a training set (the
    proxies' OUT) or a DyNeRF dataset into the model folder OUT. Options: the fields of
    pg_train_config (iters, resume, threads, seed, proxies, ...)."""
    cfg, keep = _config("train", dict(options, input=input, out=out))
    return _call("train", cfg)


def evaluate(dataset, model, out, **options):
    """Scores a model on the dataset's held-out cameras (DyNeRF protocol): OUT/metrics.json,
    OUT/report.md. Options: threads, config_json, stages_json."""
    cfg, keep = _config("evaluate", dict(options, dataset=dataset, model=model, out=out))
    return _call("evaluate", cfg)


def render(model, out, **options):
    """Videos of a trained model along a camera path. Options: the fields of pg_render_config
    (path: "fixed", "orbit", "spiral" or "dataset-cam"; camera, steps, angle, time, fps,
    write_depth, write_frames, camera_path, width, height, threads, ...)."""
    cfg, keep = _config("render", dict(options, model=model, out=out))
    return _call("render", cfg)


def export(model, out, times=None, frames=None, all_frames=False, format=None):
    """Deformed Gaussians as standard 3DGS PLY (format "ply") or .splat files: one per time in
    [0, 1] of times, per training frame of frames, or per frame (all_frames)."""
    opts = {"model": model, "out": out, "all_frames": int(bool(all_frames)), "format": format}
    cfg, keep = _config("export", opts)
    if times is not None:
        t = (C.c_float * len(times))(*[float(x) for x in times])
        cfg.times, cfg.num_times = C.cast(t, C.POINTER(C.c_float)), len(times)
        keep.append(t)
    if frames is not None:
        f = (C.c_int * len(frames))(*[int(x) for x in frames])
        cfg.frames, cfg.num_frames = C.cast(f, C.POINTER(C.c_int)), len(frames)
        keep.append(f)
    return _call("export", cfg)


def view(model, out=None, **options):
    """Writes the web viewer (index.html + scene.pgvs) of a model (default: MODEL/viewer).
    Options: frames, max_gaussians. Serving it is the CLI's `prodygs view`."""
    if out is None:
        out = os.path.join(os.fspath(model), "viewer")
    cfg, keep = _config("view", dict(options, model=model, out=out))
    return _call("view", cfg)


def run(input, out, depth=None, depth_model=None, **options):
    """The whole pipeline with resumable stage markers, as `prodygs run` (evaluate=1 and
    render_videos=0 for `prodygs eval`): depth (built-in network when neither depth nor
    depth_model is given), prepare, proxies, train, then the renders and OUT/report.md. A rerun
    skips the stages whose settings and inputs did not change. Options: the fields of
    pg_pipeline_config (preset, iters, proxies, frames, width, height, threads, seed,
    train_camera, test_cameras, evaluate, render_videos, ...). The report's "stages" says which
    stages ran and how long each took."""
    if "command" not in options:  # what report.md and metrics.json record as the command
        args = [repr(os.fspath(input)), repr(os.fspath(out))]
        if isinstance(depth, (str, bytes, os.PathLike)):
            args.append("depth=%r" % os.fspath(depth))
        elif depth is not None:
            args.append("depth=<array>")
        if depth_model is not None:
            args.append("depth_model=%r" % os.fspath(depth_model))
        args += ["%s=%r" % kv for kv in sorted(options.items())]
        options["command"] = "python3: prodygs.run(%s)" % ", ".join(args)
    if depth is None and depth_model is None:
        depth_model = default_depth_model()
    with _DepthArg(depth) as d:
        cfg, keep = _config("pipeline", dict(options, input=input, out=out, depth=d, depth_model=depth_model))
        rep = _call("pipeline", cfg)
    rep["stages"] = {name: {"ran": bool(rep["ran"][i]),
                            "seconds": rep["seconds"][i] if not math.isnan(rep["seconds"][i]) else None}
                     for i, name in enumerate(_types.PIPELINE_STAGES)}
    return rep


pipeline = run
