"""Finding and loading libprodygs.so, and declaring its functions for ctypes.

The library is looked for, in this order:
  1. $PRODYGS_LIB (a path to the .so file);
  2. beside this package (a copy dropped into the package folder);
  3. the source tree's build folder (python/prodygs -> build/), for use straight from a checkout;
  4. the install prefix (PREFIX/lib/python3/dist-packages/prodygs -> PREFIX/lib);
  5. the system's loader path (libprodygs.so.MAJOR, e.g. after `cmake --install` into /usr/local).
"""
import ctypes as C
import glob
import os

from . import _types as T

SOVERSION = "0"  # the major version of PRODYGS_VERSION: the SONAME is libprodygs.so.0
_NAME = "libprodygs.so." + SOVERSION


def _candidates():
    env = os.environ.get("PRODYGS_LIB")
    if env:
        yield env
        return
    here = os.path.dirname(os.path.abspath(__file__))
    for folder in (here,
                   os.path.join(here, "..", "..", "build"),
                   os.path.join(here, "..", "..", "..")):
        folder = os.path.normpath(folder)
        for name in (_NAME, "libprodygs.so"):
            path = os.path.join(folder, name)
            if os.path.exists(path):
                yield path
        for path in sorted(glob.glob(os.path.join(folder, "libprodygs.so.*"))):
            yield path
    yield _NAME  # the loader's own search (ld.so.cache, LD_LIBRARY_PATH)


def _load():
    tried = []
    for path in _candidates():
        try:
            return C.CDLL(path), path
        except OSError as e:
            tried.append("%s (%s)" % (path, e))
    raise ImportError("prodygs: cannot load libprodygs.so; tried: " + "; ".join(tried) +
                      ". Build it (cmake --build build) or set PRODYGS_LIB to its path.")


lib, path = _load()


def _declare(name, restype, *argtypes):
    fn = getattr(lib, name)
    fn.restype = restype
    fn.argtypes = list(argtypes)
    return fn


last_error = _declare("pg_last_error", C.c_char_p)
status_name = _declare("pg_status_name", C.c_char_p, C.c_int)
version = _declare("pg_version", C.c_char_p)
struct_size = _declare("pg_struct_size", C.c_size_t, C.c_char_p)
default_model = _declare("pg_depth_default_model", C.c_int, C.c_char_p, C.c_size_t)
WARNING_HANDLER = C.CFUNCTYPE(None, C.c_char_p, C.c_void_p)
set_warning_handler = _declare("pg_set_warning_handler", None, WARNING_HANDLER, C.c_void_p)

STAGES = {}
for _stage, _cfg, _rep in (("depth", T.DepthConfig, T.DepthReport), ("prepare", T.PrepareConfig, T.PrepareReport),
                           ("proxies", T.ProxiesConfig, T.ProxiesReport), ("train", T.TrainConfig, T.TrainReport),
                           ("evaluate", T.EvaluateConfig, T.EvaluateReport),
                           ("render", T.RenderConfig, T.RenderReport), ("export", T.ExportConfig, T.ExportReport),
                           ("view", T.ViewConfig, T.ViewReport),
                           ("pipeline", T.PipelineConfig, T.PipelineReport)):
    STAGES[_stage] = (_declare("pg_%s_defaults" % _stage, None, C.POINTER(_cfg)),
                      _declare("pg_%s_run" % _stage, C.c_int, C.POINTER(_cfg), C.POINTER(_rep)), _cfg, _rep)


def check_layout():
    """Raises ImportError when a mirrored struct's size differs from the library's."""
    bad = []
    for t in T.ALL:
        want = struct_size(t._c_name.encode())
        if want != C.sizeof(t):
            bad.append("%s: library %d bytes, python/prodygs/_types.py %d" % (t._c_name, want, C.sizeof(t)))
    if bad:
        raise ImportError("prodygs: %s (version %s) does not match this module's structs: %s"
                          % (path, version().decode(), "; ".join(bad)))


check_layout()
