#!/usr/bin/python3
"""tflite_int_ref.py - a second, independent evaluator of integer (int8 / uint8) TFLite models,
in Python + NumPy, for tests/test_nn_tflite_int.c: its own flatbuffer reader (no code shared
with src/nn) and TFLite's reference integer arithmetic written again from TFLite's definitions
(integer_ops conv / depthwise / add, quantize / requantize, QuantizeMultiplier,
MultiplyByQuantizedMultiplier).

    tflite_int_ref.py MODEL.tflite INPUT.npy OUTPUT.npy

INPUT holds the first graph input's REAL values (float32, the input's shape); OUTPUT gets the
first graph output's real values, scale * (q - zero_point) (the convention of src/nn/tflite.h).
Ops: QUANTIZE, DEQUANTIZE, CONV_2D, DEPTHWISE_CONV_2D, ADD, PAD, RESIZE_NEAREST_NEIGHBOR,
RESHAPE. Exits 2 on anything else.
"""
import math
import struct
import sys

import numpy as np


class Table:
    """A flatbuffer table at pos: field(i) gives the absolute position of field i or None."""

    def __init__(self, buf, pos):
        self.buf, self.pos = buf, pos
        self.vt = pos - struct.unpack_from("<i", buf, pos)[0]
        self.vsize = struct.unpack_from("<H", buf, self.vt)[0]

    def field(self, i):
        slot = 4 + 2 * i
        if slot + 2 > self.vsize:
            return None
        off = struct.unpack_from("<H", self.buf, self.vt + slot)[0]
        return self.pos + off if off else None

    def scalar(self, i, fmt, default):
        p = self.field(i)
        return struct.unpack_from("<" + fmt, self.buf, p)[0] if p is not None else default

    def ref(self, i):
        p = self.field(i)
        return None if p is None else p + struct.unpack_from("<I", self.buf, p)[0]

    def table(self, i):
        p = self.ref(i)
        return None if p is None else Table(self.buf, p)

    def vector(self, i, dtype):
        p = self.ref(i)
        if p is None:
            return np.zeros(0, dtype)
        n = struct.unpack_from("<I", self.buf, p)[0]
        return np.frombuffer(self.buf, dtype=dtype, count=n, offset=p + 4)

    def tables(self, i):
        p = self.ref(i)
        if p is None:
            return []
        n = struct.unpack_from("<I", self.buf, p)[0]
        out = []
        for k in range(n):
            e = p + 4 + 4 * k
            out.append(Table(self.buf, e + struct.unpack_from("<I", self.buf, e)[0]))
        return out


DTYPES = {0: np.float32, 2: np.int32, 3: np.uint8, 9: np.int8}
RANGES = {3: (0, 255), 9: (-128, 127)}


def load(path):
    buf = open(path, "rb").read()
    model = Table(buf, struct.unpack_from("<I", buf, 0)[0])
    codes = []
    for c in model.tables(1):
        codes.append(max(c.scalar(0, "b", 0), c.scalar(3, "i", 0)))
    buffers = model.tables(4)
    g = model.tables(2)[0]
    tensors = []
    for t in g.tables(0):
        shape = tuple(int(d) for d in t.vector(0, "<i4"))
        ttype = t.scalar(1, "b", 0)
        b = t.scalar(2, "I", 0)
        data = buffers[b].vector(0, np.uint8) if b < len(buffers) else np.zeros(0, np.uint8)
        q = t.table(4)
        scales = q.vector(2, "<f4") if q else np.zeros(0, np.float32)
        zps = q.vector(3, "<i8") if q else np.zeros(0, np.int64)
        qdim = q.scalar(6, "i", 0) if q else 0
        const = None
        if len(data):
            const = np.frombuffer(data.tobytes(), dtype=DTYPES[ttype]).reshape(shape)
        tensors.append(dict(shape=shape, type=ttype, scales=scales, zp=int(zps[0]) if len(zps) else 0, qdim=qdim, const=const))
    ops = []
    for o in g.tables(3):
        code = codes[o.scalar(0, "I", 0)]
        opt = o.table(4)
        ops.append(dict(code=code, inputs=[int(i) for i in o.vector(1, "<i4")], output=int(o.vector(2, "<i4")[0]), opt=opt))
    return tensors, ops, int(g.vector(1, "<i4")[0]), int(g.vector(2, "<i4")[0])


def round_half_away(v):
    return np.sign(v) * np.floor(np.abs(v) + 0.5)


def quantize_multiplier(m):
    if m == 0:
        return 0, 0
    f, shift = math.frexp(m)
    q = int(math.floor(f * 2.0 ** 31 + 0.5))
    if q == 2 ** 31:
        q //= 2
        shift += 1
    if shift < -31:
        return 0, 0
    return q, shift


def multiply_by_quantized_multiplier(x, q, shift):
    """x (int64 array) * q * 2^(shift - 31) with TFLite's two roundings; q, shift scalars or arrays."""
    q = np.asarray(q, np.int64)
    shift = np.asarray(shift, np.int64)
    left = np.maximum(shift, 0)
    right = np.maximum(-shift, 0)
    x = np.clip(x.astype(np.int64) << left, -2 ** 31, 2 ** 31 - 1)
    ab = x * q
    t = ab + np.where(ab >= 0, 1 << 30, 1 - (1 << 30))
    high = np.where(t >= 0, t >> 31, -((-t) >> 31))  # division truncating toward zero
    mask = (np.int64(1) << right) - 1
    rem = high & mask
    threshold = (mask >> 1) + (high < 0)
    return (high >> right) + (rem > threshold)


def act_range(act, t):
    lo, hi = RANGES[t["type"]]
    s, zp = np.float32(t["scales"][0]), t["zp"]
    quant = lambda v: zp + int(round_half_away(np.float32(v) / s))
    if act in (1, 3):
        lo = max(lo, quant(0.0))
    if act == 3:
        hi = min(hi, quant(6.0))
    if act == 2:
        lo, hi = max(lo, quant(-1.0)), min(hi, quant(1.0))
    return lo, hi


def same_pads(size, k, stride, dil, valid):
    dk = (k - 1) * dil + 1
    out = (size - dk) // stride + 1 if valid else (size + stride - 1) // stride
    total = max((out - 1) * stride + dk - size, 0)
    return out, (0 if valid else total // 2)


def conv(x, xt, wt, bt, yt, opt, depthwise):
    padding_valid = opt.scalar(0, "B", 0)
    sw, sh = opt.scalar(1, "i", 1), opt.scalar(2, "i", 1)
    act = opt.scalar(4 if depthwise else 3, "B", 0)
    dw, dh = (opt.scalar(5, "i", 1), opt.scalar(6, "i", 1)) if depthwise else (opt.scalar(4, "i", 1), opt.scalar(5, "i", 1))
    w = wt["const"].astype(np.int64) - wt["zp"]
    n, h, wd, c = x.shape
    kh, kw = w.shape[1], w.shape[2]
    oh, pt = same_pads(h, kh, sh, dh, padding_valid)
    ow, pl = same_pads(wd, kw, sw, dw, padding_valid)
    xc = x.astype(np.int64) - xt["zp"]
    # zero-padded centred input: padding contributes nothing, as TFLite skips it
    big = np.zeros((n, h + 2 * (kh * dh) + oh * sh, wd + 2 * (kw * dw) + ow * sw, c), np.int64)
    big[:, kh * dh:kh * dh + h, kw * dw:kw * dw + wd, :] = xc
    cout = yt["shape"][3]
    acc = np.zeros((n, oh, ow, cout), np.int64)
    for ky in range(kh):
        for kx in range(kw):
            y0 = kh * dh - pt + ky * dh
            x0 = kw * dw - pl + kx * dw
            patch = big[:, y0:y0 + (oh - 1) * sh + 1:sh, x0:x0 + (ow - 1) * sw + 1:sw, :]
            if depthwise:
                mult = cout // c
                acc += np.repeat(patch, mult, axis=3) * w[0, ky, kx, :]
            else:
                acc += patch @ w[:, ky, kx, :].T
    if bt is not None:
        acc += bt["const"].astype(np.int64)
    ws = wt["scales"] if len(wt["scales"]) > 1 else np.repeat(wt["scales"], cout)
    qs = [quantize_multiplier(float(xt["scales"][0]) * float(s) / float(yt["scales"][0])) for s in ws]
    acc = np.clip(acc, -2 ** 31, 2 ** 31 - 1)
    out = multiply_by_quantized_multiplier(acc, [q for q, _ in qs], [s for _, s in qs]) + yt["zp"]
    lo, hi = act_range(act, yt)
    return np.clip(out, lo, hi)


def add(a, at, b, bt, yt, opt):
    left = 20
    twice = 2 * max(float(at["scales"][0]), float(bt["scales"][0]))
    qa, sa = quantize_multiplier(float(at["scales"][0]) / twice)
    qb, sb = quantize_multiplier(float(bt["scales"][0]) / twice)
    qy, sy = quantize_multiplier(twice / ((1 << left) * float(yt["scales"][0])))
    va = multiply_by_quantized_multiplier((a.astype(np.int64) - at["zp"]) << left, qa, sa)
    vb = multiply_by_quantized_multiplier((b.astype(np.int64) - bt["zp"]) << left, qb, sb)
    out = multiply_by_quantized_multiplier(va + vb, qy, sy) + yt["zp"]
    lo, hi = act_range(opt.scalar(0, "B", 0) if opt else 0, yt)
    return np.clip(out, lo, hi)


def nearest(x, yt, opt):
    align = opt.scalar(0, "B", 0) if opt else 0
    half = opt.scalar(1, "B", 0) if opt else 0
    _, h, w, _ = x.shape
    oh, ow = yt["shape"][1], yt["shape"][2]

    def index(size, out):
        scale = np.float32((size - 1) / (out - 1)) if align and out > 1 else np.float32(size) / np.float32(out)
        f = (np.arange(out, dtype=np.float32) + np.float32(0.5 if half else 0.0)) * scale
        i = round_half_away(f) if align else np.floor(f)
        return np.clip(i.astype(np.int64), 0, size - 1)

    return x[:, index(h, oh)][:, :, index(w, ow)]


def run(path, x_real):
    tensors, ops, inp, outp = load(path)
    vals = {}
    it = tensors[inp]
    if it["type"] in RANGES:
        lo, hi = RANGES[it["type"]]
        q = round_half_away(x_real.astype(np.float32) / np.float32(it["scales"][0])) + it["zp"]
        vals[inp] = np.clip(q, lo, hi).astype(np.int64)
    else:
        vals[inp] = x_real.astype(np.float32)
    for op in ops:
        code, ins, out, opt = op["code"], op["inputs"], op["output"], op["opt"]
        xt, yt = tensors[ins[0]], tensors[out]
        x = vals.get(ins[0])
        if code == 114:  # QUANTIZE
            lo, hi = RANGES[yt["type"]]
            if xt["type"] == 0:
                y = round_half_away(x / np.float32(yt["scales"][0])) + yt["zp"]
            else:
                q, s = quantize_multiplier(float(xt["scales"][0]) / float(yt["scales"][0]))
                y = multiply_by_quantized_multiplier(x - xt["zp"], q, s) + yt["zp"]
            y = np.clip(y, lo, hi).astype(np.int64)
        elif code == 6:  # DEQUANTIZE
            y = ((x - xt["zp"]) * np.float64(xt["scales"][0])).astype(np.float32)
        elif code in (3, 4):
            bt = tensors[ins[2]] if len(ins) > 2 and ins[2] >= 0 else None
            y = conv(x, xt, tensors[ins[1]], bt, yt, opt, code == 4)
        elif code == 0:
            y = add(x, xt, vals[ins[1]], tensors[ins[1]], yt, opt)
        elif code == 34:  # PAD with the zero point
            p = tensors[ins[1]]["const"].reshape(-1, 2)
            y = np.pad(x, [(int(a), int(b)) for a, b in p], constant_values=yt["zp"])
        elif code == 97:
            y = nearest(x, yt, opt)
        elif code == 22:
            y = x.reshape(yt["shape"])
        else:
            print("tflite_int_ref.py: op %d is not supported" % code, file=sys.stderr)
            sys.exit(2)
        vals[out] = y
    ot, y = tensors[outp], vals[outp]
    if ot["type"] in RANGES:
        return ((y - ot["zp"]) * np.float64(ot["scales"][0])).astype(np.float32)
    return y.astype(np.float32)


if __name__ == "__main__":
    if len(sys.argv) != 4:
        print(__doc__, file=sys.stderr)
        sys.exit(2)
    np.save(sys.argv[3], run(sys.argv[1], np.load(sys.argv[2])))
