#!/usr/bin/env bash
# install_pkgconfig.sh BUILD_DIR SOURCE_DIR CC - the C user's way in: `cmake --install` into a
# fresh prefix, docs/example_pipeline.c compiled against that copy with nothing but pkg-config,
# then run on a small synthetic dataset (the four stages in-process, from the shared library).
set -euo pipefail
build=$1 src=$2 cc=${3:-cc}
tmp=$build/test-tmp/install_pkgconfig
rm -rf "$tmp" && mkdir -p "$tmp"
prefix=$tmp/prefix
cmake --install "$build" --prefix "$prefix" >"$tmp/install.log"
pc=$prefix/lib/pkgconfig/prodygs.pc
test -f "$pc" || { echo "no $pc"; exit 1; }
grep -q "^prefix=$prefix\$" "$pc" || { echo "prodygs.pc names another prefix:"; cat "$pc"; exit 1; }
so=$(readlink -f "$prefix/lib/libprodygs.so")
soname=$(objdump -p "$so" | awk '$1=="SONAME"{print $2}')
case $soname in libprodygs.so.[0-9]*) ;; *) echo "SONAME '$soname'"; exit 1 ;; esac
test -e "$prefix/lib/$soname" || { echo "$soname is not installed"; exit 1; }
# only the public API is exported
others=$(nm -D --defined-only "$so" | awk '$2=="T" && $3 !~ /^pg_/ {print $3}')
[ -z "$others" ] || { echo "libprodygs.so exports non-pg_ symbols:"; echo "$others" | head; exit 1; }
flags=$(PKG_CONFIG_PATH=$prefix/lib/pkgconfig pkg-config --cflags --libs prodygs)
echo "pkg-config --cflags --libs prodygs: $flags"
"$cc" -Wall -Wextra -Werror "$src/docs/example_pipeline.c" $flags -o "$tmp/example"
# it runs from the installed shared library, found through the rpath alone
deps=$(ldd "$tmp/example")   # (not piped into grep -q: an early exit would fail the pipe)
grep -q "$prefix/lib/$soname" <<<"$deps" || { echo "example does not load the installed library:"; echo "$deps"; exit 1; }
"$prefix/bin/prodygs" synth "$tmp/data" --cams 7 --frames 3 --size 32x24 --spp 1 --threads 2 >"$tmp/synth.log" 2>&1
OMP_WAIT_POLICY=PASSIVE "$tmp/example" "$tmp/data" "$tmp/data/depth_mono/cam00.npy" "$tmp/out" | tee "$tmp/example.log"
grep -q '^evaluate: ' "$tmp/example.log"
test -f "$tmp/out/metrics.json"
# the Python module installed beside it finds that library by itself and runs a stage
py=${PYTHON3:-/usr/bin/python3}
site=$prefix/lib/python3/dist-packages
if [ -x "$py" ] && "$py" -c "import numpy" 2>/dev/null; then
  (cd "$tmp" && env -u PRODYGS_LIB PYTHONPATH="$site" "$py" -c "import prodygs; assert prodygs.library_path.startswith('$prefix/lib/'), prodygs.library_path; d = prodygs.depth('data/cam00/images', frames=2, threads=2); print('python: prodygs', prodygs.version(), 'from', prodygs.library_path, 'depth', d.shape, d.dtype)")
else
  echo "install_pkgconfig: python3 with numpy not found: the installed module is not tried here"
fi
echo "install_pkgconfig: ok ($soname)"
