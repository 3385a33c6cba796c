#!/usr/bin/python3
"""make_onnx_models.py - ONNX test models and their torch outputs for tests/test_nn_onnx.c.

    /usr/bin/python3 tests/nn/make_onnx_models.py OUTDIR            # op cases + the ViT-S/DPT net
    /usr/bin/python3 tests/nn/make_onnx_models.py --bench FILE.onnx  # the net at 518x392 only

For every case NAME it writes OUTDIR/NAME.onnx, NAME_in.npy (float32 input) and NAME_out.npy
(torch's float32 output), and lists NAME in OUTDIR/cases.txt. The whole network ("net") has three
inputs/outputs: net_in0..2.npy, net_out0..2.npy. Exits 77 when torch or onnx is missing.
Weights are seeded random (torch.manual_seed), exported with opset 17.
"""
import math
import os
import sys

try:
    import numpy as np
    import torch
    import torch.nn as nn
    import torch.nn.functional as F
    import onnx  # noqa: F401  (torch.onnx.export needs it)
except Exception as e:  # pragma: no cover
    print("make_onnx_models: torch/onnx not available (%s)" % e)
    sys.exit(77)

OPSET = 17


# ---- a Depth-Anything-V2-small-shaped network: ViT-S/14 encoder + DPT head ----

class Attention(nn.Module):
    def __init__(self, dim, heads):
        super().__init__()
        self.heads = heads
        self.scale = (dim // heads) ** -0.5
        self.qkv = nn.Linear(dim, dim * 3)
        self.proj = nn.Linear(dim, dim)

    def forward(self, x):
        B, N, C = x.shape
        qkv = self.qkv(x).reshape(B, N, 3, self.heads, C // self.heads).permute(2, 0, 3, 1, 4)
        q, k, v = qkv[0] * self.scale, qkv[1], qkv[2]
        attn = (q @ k.transpose(-2, -1)).softmax(dim=-1)
        x = (attn @ v).transpose(1, 2).reshape(B, N, C)
        return self.proj(x)


class Block(nn.Module):
    def __init__(self, dim, heads, mlp):
        super().__init__()
        self.norm1 = nn.LayerNorm(dim, eps=1e-6)
        self.attn = Attention(dim, heads)
        self.ls1 = nn.Parameter(torch.rand(dim) * 0.5 + 0.5)
        self.norm2 = nn.LayerNorm(dim, eps=1e-6)
        self.fc1 = nn.Linear(dim, mlp)
        self.fc2 = nn.Linear(mlp, dim)
        self.ls2 = nn.Parameter(torch.rand(dim) * 0.5 + 0.5)

    def forward(self, x):
        x = x + self.ls1 * self.attn(self.norm1(x))
        return x + self.ls2 * self.fc2(F.gelu(self.fc1(self.norm2(x))))


class RCU(nn.Module):
    def __init__(self, f):
        super().__init__()
        self.conv1 = nn.Conv2d(f, f, 3, padding=1)
        self.conv2 = nn.Conv2d(f, f, 3, padding=1)

    def forward(self, x):
        return self.conv2(F.relu(self.conv1(F.relu(x)))) + x


class Fusion(nn.Module):
    def __init__(self, f):
        super().__init__()
        self.rcu1 = RCU(f)
        self.rcu2 = RCU(f)
        self.out_conv = nn.Conv2d(f, f, 1)

    def forward(self, x, skip=None, size=None):
        if skip is not None:
            x = x + self.rcu1(skip)
        x = self.rcu2(x)
        if size is None:
            x = F.interpolate(x, scale_factor=2.0, mode="bilinear", align_corners=True)
        else:
            x = F.interpolate(x, size=size, mode="bilinear", align_corners=True)
        return self.out_conv(x)


class DepthNet(nn.Module):
    """ViT-S/14 (embed 384, 12 blocks, 6 heads, MLP 1536, LayerScale, cls token, a 37x37 position
    embedding interpolated bicubically to the patch grid as DINOv2 does, scale (n + 0.1) / 37)
    + DPT head (layers 2, 5, 8, 11; features 64; out channels 48, 96, 192, 384)."""

    def __init__(self, h, w, dim=384, depth=12, heads=6, mlp=1536, feat=64, outc=(48, 96, 192, 384)):
        super().__init__()
        self.ph, self.pw = h // 14, w // 14
        self.patch = nn.Conv2d(3, dim, 14, 14)
        self.cls = nn.Parameter(torch.randn(1, 1, dim) * 0.02)
        self.pos = nn.Parameter(torch.randn(1, 1 + 37 * 37, dim) * 0.02)
        self.blocks = nn.ModuleList([Block(dim, heads, mlp) for _ in range(depth)])
        self.norm = nn.LayerNorm(dim, eps=1e-6)
        self.take = [2, 5, 8, 11] if depth == 12 else list(range(depth))[-4:]
        self.projects = nn.ModuleList([nn.Conv2d(dim, c, 1) for c in outc])
        self.resize = nn.ModuleList([
            nn.ConvTranspose2d(outc[0], outc[0], 4, stride=4),
            nn.ConvTranspose2d(outc[1], outc[1], 2, stride=2),
            nn.Identity(),
            nn.Conv2d(outc[3], outc[3], 3, stride=2, padding=1)])
        self.rn = nn.ModuleList([nn.Conv2d(c, feat, 3, padding=1, bias=False) for c in outc])
        self.fuse = nn.ModuleList([Fusion(feat) for _ in range(4)])
        self.out1 = nn.Conv2d(feat, feat // 2, 3, padding=1)
        self.out2a = nn.Conv2d(feat // 2, 32, 3, padding=1)
        self.out2b = nn.Conv2d(32, 1, 1)
        with torch.no_grad():
            self.out2b.bias.fill_(0.05)  # positive output (a depth map), not a ReLU of mostly negatives

    def forward(self, img):
        B = img.shape[0]
        x = self.patch(img).flatten(2).transpose(1, 2)
        C = x.shape[-1]
        grid = self.pos[:, 1:].reshape(1, 37, 37, C).permute(0, 3, 1, 2)
        grid = F.interpolate(grid, scale_factor=(float((self.ph + 0.1) / 37), float((self.pw + 0.1) / 37)),
                             mode="bicubic", align_corners=False)
        pos = torch.cat([self.pos[:, :1], grid.permute(0, 2, 3, 1).reshape(1, -1, C)], dim=1)
        x = torch.cat([self.cls.expand(B, -1, -1), x], dim=1) + pos
        feats = []
        for i, blk in enumerate(self.blocks):
            x = blk(x)
            if i in self.take:
                feats.append(self.norm(x)[:, 1:])
        layers = []
        for i, f in enumerate(feats):
            f = f.permute(0, 2, 1).reshape(B, f.shape[-1], self.ph, self.pw)
            layers.append(self.rn[i](self.resize[i](self.projects[i](f))))
        l1, l2, l3, l4 = layers
        p4 = self.fuse[3](l4, size=l3.shape[2:])
        p3 = self.fuse[2](p4, l3, size=l2.shape[2:])
        p2 = self.fuse[1](p3, l2, size=l1.shape[2:])
        p1 = self.fuse[0](p2, l1)
        out = self.out1(p1)
        out = F.interpolate(out, (self.ph * 14, self.pw * 14), mode="bilinear", align_corners=True)
        out = F.relu(self.out2b(F.relu(self.out2a(out))))
        return F.relu(out).squeeze(1)


def seeded_images(n, h, w, seed=3):
    """Smooth synthetic RGB images (gradients, discs, noise), ImageNet-normalised."""
    g = np.random.default_rng(seed)
    yy, xx = np.mgrid[0:h, 0:w].astype(np.float32)
    out = []
    for _ in range(n):
        img = np.zeros((3, h, w), np.float32)
        for c in range(3):
            a, b = g.uniform(-1, 1, 2)
            img[c] = 0.5 + 0.3 * (a * xx / w + b * yy / h)
            for _ in range(4):
                cx, cy, r = g.uniform(0, w), g.uniform(0, h), g.uniform(10, h / 3)
                img[c] += g.uniform(-0.4, 0.4) * ((xx - cx) ** 2 + (yy - cy) ** 2 < r * r)
        img += g.normal(0, 0.03, img.shape).astype(np.float32)
        mean = np.array([0.485, 0.456, 0.406], np.float32)[:, None, None]
        std = np.array([0.229, 0.224, 0.225], np.float32)[:, None, None]
        out.append(((np.clip(img, 0, 1) - mean) / std)[None].astype(np.float32))
    return out


# ---- one module per op (or small op pattern) ----

class Lambda(nn.Module):
    def __init__(self, fn, **params):
        super().__init__()
        self.fn = fn
        for k, v in params.items():
            setattr(self, k, v)

    def forward(self, x):
        return self.fn(self, x)


def P(*shape):
    return nn.Parameter(torch.randn(*shape))


def op_cases():
    """(name, module, input shape) for every op the runtime supports."""
    t = torch
    c = []
    c.append(("conv3x3", nn.Conv2d(3, 8, 3, padding=1), (1, 3, 17, 13)))
    c.append(("conv_stride_dil_group", nn.Conv2d(8, 12, 3, stride=2, padding=2, dilation=2, groups=4), (2, 8, 15, 18)))
    c.append(("conv_patch14", nn.Conv2d(3, 32, 14, 14), (1, 3, 56, 42)))
    c.append(("conv_depthwise", nn.Conv2d(6, 6, 5, padding=(2, 1), groups=6), (1, 6, 9, 11)))
    c.append(("conv_1x1", nn.Conv2d(16, 8, 1), (1, 16, 7, 9)))
    c.append(("conv_asym_pad", Lambda(lambda m, x: m.c(F.pad(x, (1, 0, 2, 1))), c=nn.Conv2d(4, 5, 3)), (1, 4, 8, 8)))
    c.append(("convtranspose_k4s4", nn.ConvTranspose2d(8, 4, 4, stride=4), (1, 8, 5, 6)))
    c.append(("convtranspose_k3s2", nn.ConvTranspose2d(8, 6, 3, stride=2, padding=1, output_padding=1, groups=2), (1, 8, 5, 7)))
    c.append(("matmul_weight", Lambda(lambda m, x: x @ m.w, w=P(24, 16)), (2, 5, 24)))
    c.append(("matmul_batched", Lambda(lambda m, x: x @ x.transpose(-2, -1)), (2, 3, 7, 5)))
    c.append(("gemm_linear", nn.Linear(20, 12), (6, 20)))
    c.append(("add_broadcast", Lambda(lambda m, x: x + m.b, b=P(1, 4, 1, 1)), (2, 4, 3, 5)))
    c.append(("sub_mul_div", Lambda(lambda m, x: (x - m.a) * m.b / (m.c.abs() + 0.5), a=P(5), b=P(3, 1), c=P(1, 5)), (2, 3, 5)))
    c.append(("pow_sqrt", Lambda(lambda m, x: t.sqrt(x.pow(2) + 1.0) + x.abs().pow(1.5)), (3, 9)))
    c.append(("erf", Lambda(lambda m, x: t.erf(x)), (4, 33)))
    c.append(("layernorm", nn.LayerNorm(24, eps=1e-6), (2, 7, 24)))
    c.append(("layernorm_decomposed", Lambda(lambda m, x: (x - x.mean(-1, keepdim=True)) /
                                             t.sqrt(((x - x.mean(-1, keepdim=True)) ** 2).mean(-1, keepdim=True) + 1e-5) * m.g + m.b,
                                             g=P(24), b=P(24)), (2, 7, 24)))
    c.append(("softmax_last", Lambda(lambda m, x: t.softmax(x * 3, dim=-1)), (2, 3, 11)))
    c.append(("softmax_mid", Lambda(lambda m, x: t.softmax(x * 3, dim=1)), (2, 5, 4)))
    c.append(("reducemean", Lambda(lambda m, x: x.mean(dim=(1, 3), keepdim=False)), (2, 3, 4, 5)))
    c.append(("reshape_transpose", Lambda(lambda m, x: x.reshape(2, 3, 4, 5).permute(0, 2, 3, 1).reshape(2, -1)), (6, 20)))
    c.append(("slice_steps", Lambda(lambda m, x: x[:, 1:, ::2, 3:-1]), (2, 3, 9, 10)))
    c.append(("concat_gather", Lambda(lambda m, x: t.cat([x[:, 0], x[:, 2], x[:, -1]], dim=-1)), (2, 4, 6)))
    c.append(("unsqueeze_expand", Lambda(lambda m, x: x.unsqueeze(1).expand(-1, 3, -1, -1) * m.s, s=P(3, 1, 1)), (2, 4, 5)))
    c.append(("flatten_squeeze", Lambda(lambda m, x: x.flatten(1).unsqueeze(-1).squeeze(-1) + 1), (2, 3, 4)))
    c.append(("resize_bilinear_align", Lambda(lambda m, x: F.interpolate(x, size=(13, 17), mode="bilinear", align_corners=True)), (1, 2, 5, 7)))
    c.append(("resize_bilinear_half", Lambda(lambda m, x: F.interpolate(x, size=(11, 4), mode="bilinear", align_corners=False)), (1, 2, 5, 7)))
    c.append(("resize_bilinear_scale", Lambda(lambda m, x: F.interpolate(x, scale_factor=2.0, mode="bilinear", align_corners=False)), (1, 3, 6, 5)))
    c.append(("resize_bicubic", Lambda(lambda m, x: F.interpolate(x, scale_factor=(1.7, 0.8), mode="bicubic", align_corners=False)), (1, 2, 9, 11)))
    c.append(("resize_bicubic_align", Lambda(lambda m, x: F.interpolate(x, size=(12, 5), mode="bicubic", align_corners=True)), (1, 2, 7, 9)))
    c.append(("resize_nearest", Lambda(lambda m, x: F.interpolate(x, scale_factor=3.0, mode="nearest")), (1, 2, 4, 5)))
    c.append(("relu_sigmoid", Lambda(lambda m, x: t.relu(x) + t.sigmoid(x)), (3, 40)))
    c.append(("gelu_erf", nn.GELU(), (3, 40)))
    c.append(("gelu_tanh", nn.GELU(approximate="tanh"), (3, 40)))
    c.append(("leakyrelu_max", Lambda(lambda m, x: F.leaky_relu(x, 0.2) + t.maximum(x, m.a), a=P(40)), (3, 40)))
    c.append(("pad_reflect", Lambda(lambda m, x: F.pad(x, (2, 1, 1, 2), mode="reflect")), (1, 2, 5, 6)))
    c.append(("pad_edge_constant", Lambda(lambda m, x: F.pad(F.pad(x, (3, 0, 2, 1), mode="replicate"), (1, 2, 0, 1), value=1.5)),
                                   (1, 2, 4, 5)))
    c.append(("attention_head", Attention(32, 4), (1, 9, 32)))
    # a whole ViT block at opset 13: LayerNorm decomposed by the exporter, Unsqueeze/Squeeze axes as inputs
    c.append(("vit_block_opset13", Block(48, 4, 96), (1, 10, 48), 13))
    return c


def resize_reference(x, out_h, out_w, mode, coord, nearest):
    """ONNX Resize of the last two dims with sizes given (scale = out / in), written from the spec."""
    def axis(in_len, out_len):
        scale = out_len / in_len
        w = np.zeros((out_len, in_len))
        for o in range(out_len):
            if coord == "half_pixel":
                c = (o + 0.5) / scale - 0.5
            elif coord == "pytorch_half_pixel":
                c = (o + 0.5) / scale - 0.5 if out_len > 1 else 0.0
            elif coord == "align_corners":
                c = o * (in_len - 1) / (out_len - 1) if out_len > 1 else 0.0
            elif coord == "asymmetric":
                c = o / scale
            else:  # tf_half_pixel_for_nn
                c = (o + 0.5) / scale
            if mode == "nearest":
                f = math.floor(c)
                d = c - f
                i = {"round_prefer_floor": f + (d > 0.5), "round_prefer_ceil": f + (d >= 0.5),
                     "floor": f, "ceil": math.ceil(c)}[nearest]
                w[o, min(max(i, 0), in_len - 1)] = 1
            else:
                c = min(max(c, 0), in_len - 1)
                f = int(math.floor(c))
                w[o, f] += 1 - (c - f)
                w[o, min(f + 1, in_len - 1)] += c - f
        return w
    wh, ww = axis(x.shape[2], out_h), axis(x.shape[3], out_w)
    return np.einsum("ah,nchw,bw->ncab", wh, x.astype(np.float64), ww)


def resize_modes_model(out):
    """Every coordinate mode (linear) and nearest rounding mode in one model, outputs flattened and
    concatenated, with the numpy reference above (torch only emits three of the modes)."""
    from onnx import TensorProto, helper, numpy_helper
    r = np.random.default_rng(4)
    x = r.standard_normal((1, 2, 5, 7)).astype(np.float32)
    combos = [("linear", c, "floor") for c in ("half_pixel", "pytorch_half_pixel", "align_corners", "asymmetric",
                                                  "tf_half_pixel_for_nn")]
    combos += [("nearest", c, n) for c in ("asymmetric", "half_pixel") for n in ("round_prefer_floor", "round_prefer_ceil",
                                                                                  "floor", "ceil")]
    sizes = [(11, 3), (1, 9), (4, 1), (13, 16)]
    nodes, inits, parts, refs = [], [], [], []
    for k, (mode, coord, nearest) in enumerate(combos):
        oh, ow = sizes[k % len(sizes)]
        inits.append(numpy_helper.from_array(np.array([1, 2, oh, ow], np.int64), "sizes%d" % k))
        nodes.append(helper.make_node("Resize", ["input", "", "", "sizes%d" % k], ["r%d" % k], mode=mode,
                                      coordinate_transformation_mode=coord, nearest_mode=nearest))
        nodes.append(helper.make_node("Reshape", ["r%d" % k, "flat"], ["f%d" % k]))
        parts.append("f%d" % k)
        refs.append(resize_reference(x, oh, ow, mode, coord, nearest).reshape(-1))
    inits.append(numpy_helper.from_array(np.array([-1], np.int64), "flat"))
    nodes.append(helper.make_node("Concat", parts, ["output"], axis=0))
    ref = np.concatenate(refs).astype(np.float32)
    graph = helper.make_graph(nodes, "resize_modes", [helper.make_tensor_value_info("input", TensorProto.FLOAT, list(x.shape))],
                              [helper.make_tensor_value_info("output", TensorProto.FLOAT, [ref.size])], inits)
    m = helper.make_model(graph, opset_imports=[helper.make_opsetid("", 17)])
    m.ir_version = 8
    onnx.save(m, os.path.join(out, "resize_modes.onnx"))
    np.save(os.path.join(out, "resize_modes_in.npy"), x)
    np.save(os.path.join(out, "resize_modes_out.npy"), ref)


def export(module, inputs, path, opset=OPSET):
    module.eval()
    with torch.no_grad():
        torch.onnx.export(module, (inputs,), path, opset_version=opset, input_names=["input"],
                          output_names=["output"], do_constant_folding=True)


def main():
    torch.manual_seed(0)
    if len(sys.argv) == 3 and sys.argv[1] == "--bench":
        torch.manual_seed(10)
        net = DepthNet(392, 518)
        export(net, torch.from_numpy(seeded_images(1, 392, 518)[0]), sys.argv[2])
        return 0
    if len(sys.argv) != 2:
        print(__doc__)
        return 2
    out = sys.argv[1]
    os.makedirs(out, exist_ok=True)
    names = []
    g = torch.Generator().manual_seed(1)
    for case in op_cases():
        name, mod, shape = case[:3]
        x = torch.randn(*shape, generator=g)
        export(mod, x, os.path.join(out, name + ".onnx"), case[3] if len(case) > 3 else OPSET)
        with torch.no_grad():
            y = mod(x)
        np.save(os.path.join(out, name + "_in.npy"), x.numpy().astype(np.float32))
        np.save(os.path.join(out, name + "_out.npy"), y.numpy().astype(np.float32))
        names.append(name)
    # dynamic axes: exported at 32x48, run at 45x61 (the C test binds the size with nn_model_load_shaped)
    dyn = Lambda(lambda m, x: m.b(F.interpolate(F.relu(m.a(x)), size=x.shape[2:], mode="bilinear", align_corners=False)) + x,
                 a=nn.Conv2d(3, 8, 3, stride=2, padding=1), b=nn.Conv2d(8, 3, 3, padding=1)).eval()
    with torch.no_grad():
        torch.onnx.export(dyn, (torch.randn(1, 3, 32, 48),), os.path.join(out, "dyn_conv_resize.onnx"), opset_version=OPSET,
                          input_names=["input"], output_names=["output"], do_constant_folding=True,
                          dynamic_axes={"input": {2: "h", 3: "w"}, "output": {2: "h", 3: "w"}})
        x = torch.randn(1, 3, 45, 61, generator=g)
        np.save(os.path.join(out, "dyn_conv_resize_in.npy"), x.numpy())
        np.save(os.path.join(out, "dyn_conv_resize_out.npy"), dyn(x).numpy())
    names.append("dyn_conv_resize")
    resize_modes_model(out)
    names.append("resize_modes")
    # weights stored as float16 and as per-channel int8 + DequantizeLinear (numpy reference)
    from onnx import TensorProto, helper, numpy_helper
    r = np.random.default_rng(2)
    x = r.standard_normal((3, 16)).astype(np.float32)
    w16 = r.standard_normal((16, 8)).astype(np.float16)
    q8 = r.integers(-128, 128, (8, 16)).astype(np.int8)
    scale = (r.random(8) * 0.02 + 0.01).astype(np.float32)
    zp = r.integers(-5, 5, 8).astype(np.int8)
    wq = ((q8.astype(np.float32) - zp[:, None].astype(np.float32)) * scale[:, None]).T
    nodes = [helper.make_node("Cast", ["w16"], ["w16f"], to=TensorProto.FLOAT),
             helper.make_node("MatMul", ["input", "w16f"], ["a"]),
             helper.make_node("DequantizeLinear", ["q8", "scale", "zp"], ["wq"], axis=0),
             helper.make_node("Transpose", ["wq"], ["wqt"], perm=[1, 0]),
             helper.make_node("MatMul", ["input", "wqt"], ["b"]),
             helper.make_node("Concat", ["a", "b"], ["output"], axis=1)]
    graph = helper.make_graph(nodes, "quant", [helper.make_tensor_value_info("input", TensorProto.FLOAT, [3, 16])],
                              [helper.make_tensor_value_info("output", TensorProto.FLOAT, [3, 16])],
                              [numpy_helper.from_array(w16, "w16"), numpy_helper.from_array(q8, "q8"),
                               numpy_helper.from_array(scale, "scale"), numpy_helper.from_array(zp, "zp")])
    mq = helper.make_model(graph, opset_imports=[helper.make_opsetid("", 17)])
    mq.ir_version = 8
    onnx.save(mq, os.path.join(out, "weights_fp16_int8.onnx"))
    np.save(os.path.join(out, "weights_fp16_int8_in.npy"), x)
    ref = np.concatenate([x.astype(np.float64) @ w16.astype(np.float64), x.astype(np.float64) @ wq.astype(np.float64)], 1)
    np.save(os.path.join(out, "weights_fp16_int8_out.npy"), ref.astype(np.float32))
    names.append("weights_fp16_int8")
    # the whole network at 266x196 (19x14 patches) on three images; its own seed, so adding op cases
    # above does not change it
    h, w = 196, 266
    torch.manual_seed(10)
    net = DepthNet(h, w).eval()
    imgs = seeded_images(3, h, w)
    export(net, torch.from_numpy(imgs[0]), os.path.join(out, "net.onnx"))
    with torch.no_grad():
        for i, im in enumerate(imgs):
            np.save(os.path.join(out, "net_in%d.npy" % i), im)
            y = net(torch.from_numpy(im)).numpy().astype(np.float32)
            if (y > 0).mean() < 0.5 or y.std() <= 0:
                print("make_onnx_models: the test network's output is degenerate (%.2f positive)" % (y > 0).mean())
                return 1
            np.save(os.path.join(out, "net_out%d.npy" % i), y)
    with open(os.path.join(out, "cases.txt"), "w") as f:
        f.write("\n".join(names) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
