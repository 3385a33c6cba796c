"""The ctypes mirror (python/prodygs/_types.py) against the C header, field by field.

Generates a C program that prints sizeof, alignof and offsetof every field of every mirrored
struct, compiles it against include/prodygs.h (CC, default cc) and compares each number with
ctypes'. A field added, removed, retyped or moved in the header without the mirror fails here
(and a size change already fails at import, through pg_struct_size).

    PRODYGS_INCLUDE=include python3 python/tests/test_layout.py
"""
import ctypes
import os
import subprocess
import sys
import tempfile

here = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(here, ".."))
import prodygs  # noqa: E402
from prodygs import _types  # noqa: E402


def c_program():
    lines = ["#include <prodygs.h>", "#include <stddef.h>", "#include <stdalign.h>", "#include <stdio.h>",
             "int main(void)", "{"]
    for t in _types.ALL:
        n = t._c_name
        lines.append('    printf("%s sizeof %%zu\\n", sizeof(%s));' % (n, n))
        lines.append('    printf("%s alignof %%zu\\n", alignof(%s));' % (n, n))
        for field, ftype in t._fields_:
            lines.append('    printf("%s.%s offsetof %%zu\\n", offsetof(%s, %s));' % (n, field, n, field))
            lines.append('    printf("%s.%s sizeof %%zu\\n", sizeof(((%s *)0)->%s));' % (n, field, n, field))
    lines += ["    return 0;", "}"]
    return "\n".join(lines) + "\n"


def python_side():
    out = []
    for t in _types.ALL:
        n = t._c_name
        out.append("%s sizeof %d" % (n, ctypes.sizeof(t)))
        out.append("%s alignof %d" % (n, ctypes.alignment(t)))
        for field, ftype in t._fields_:
            out.append("%s.%s offsetof %d" % (n, field, getattr(t, field).offset))
            out.append("%s.%s sizeof %d" % (n, field, ctypes.sizeof(ftype)))
    return out


def main():
    include = os.environ.get("PRODYGS_INCLUDE", os.path.join(here, "..", "..", "include"))
    cc = os.environ.get("CC", "cc")
    with tempfile.TemporaryDirectory(prefix="prodygs-layout-") as tmp:
        src, exe = os.path.join(tmp, "layout.c"), os.path.join(tmp, "layout")
        with open(src, "w") as f:
            f.write(c_program())
        subprocess.run([cc, "-std=c11", "-Wall", "-Wextra", "-Werror", "-I", include, src, "-o", exe], check=True)
        c_side = subprocess.run([exe], check=True, capture_output=True, text=True).stdout.split("\n")[:-1]
    py_side = python_side()
    assert len(c_side) == len(py_side), (len(c_side), len(py_side))
    bad = [(c, p) for c, p in zip(c_side, py_side) if c != p]
    for c, p in bad:
        print("MISMATCH  C: %-60s python: %s" % (c, p))
    fields = sum(len(t._fields_) for t in _types.ALL)
    print("test_layout: %d structs, %d fields compared with the C header: %s"
          % (len(_types.ALL), fields, "ok" if not bad else "%d differ" % len(bad)))
    # the import-time check saw the same sizes in the loaded library
    for t in _types.ALL:
        assert prodygs._lib.struct_size(t._c_name.encode()) == ctypes.sizeof(t), t._c_name
    assert prodygs._lib.struct_size(b"no_such_struct") == 0
    assert prodygs.version() == prodygs._lib.version().decode()
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
