/* depth_net.h - per-frame depth from a monocular depth network (a TFLite or ONNX file run by the
 * nn runtime): frame -> model input size -> network -> depth at the size asked for.
 *
 *   depth_net *net;
 *   PG_TRY(depth_net_open("pydnet++_matterport.tflite", NULL, 0, frame.width, frame.height, &net));
 *   float *depth = ...;                       (width * height floats)
 *   PG_TRY(depth_net_infer(net, &frame, depth, width, height, 2));
 *   depth_net_close(net);
 *
 * How the network's input and output are read comes, in this order, from the override `kind`,
 * the sidecar JSON beside the model (MODEL.json, e.g. pydnet++_matterport.tflite.json), and the
 * defaults of the model's format:
 *
 *   {"name": "PyDNet++ (Matterport)", "license": "research only",
 *    "input_size": [640, 448],            width, height: must equal a fixed-size model's input
 *    "mean": [0, 0, 0], "std": [1, 1, 1],  input = (rgb - mean) / std, rgb in [0, 1]
 *    "channel_order": "rgb",              or "bgr": the network's channel k is the frame's 2 - k
 *                                         (mean / std are in the network's order)
 *    "output": "depth",                   or "disparity" (larger = nearer)
 *    "scale": 1,                          raw output multiplied by this
 *    "multiple_of": 14}                   dynamic-input models: input sides are multiples of this
 *
 *   defaults  TFLite: mean 0, std 1 (float input in [0, 1]), output depth, scale 1.
 *             ONNX:   ImageNet mean/std (0.485 0.456 0.406 / 0.229 0.224 0.225), output
 *                     disparity (the MiDaS / Depth Anything convention), scale 1.
 *
 * A model whose input has symbolic dims (an ONNX export with dynamic axes) is loaded as NCHW
 * (1, 3, H, W) with the longer side `size` and the frame's aspect, both sides rounded to a
 * multiple of multiple_of (default 14, the patch of ViT depth models); without a size, at the
 * sidecar's input_size; with neither it is refused with a message asking for one.
 *
 * The input layout follows the model's input shape: (1, H, W, 3) is NHWC, (1, 3, H, W) NCHW; the
 * output is the first graph output with two dims > 1 (1xHxWx1, 1x1xHxW, 1xHxW or HxW). Disparity
 * is converted to depth (1 / d; d <= 0 gives 0 = invalid), so depth_net_infer always returns
 * depth: larger = farther, in the model's relative units.
 */
#ifndef PG_DEPTH_NET_H
#define PG_DEPTH_NET_H

#include "core/image.h"
#include "core/status.h"

typedef struct depth_net depth_net;

typedef struct {
    char name[128], license[128], format[8]; /* format: "tflite" or "onnx" */
    int width, height;    /* network input */
    int out_width, out_height;
    int nchw;             /* input layout */
    float mean[3], std[3];
    int bgr;              /* the network takes blue, green, red */
    int disparity;        /* raw output is disparity */
    float scale;
    int sidecar;          /* 1 when MODEL.json was read */
    int dynamic;          /* the input size was chosen here (symbolic dims in the file) */
    int flip;             /* the output is the mean of the frame's and the mirrored frame's (mirrored
                             back): 1 unless MODEL.json says "flip_average": false */
} depth_net_info;

/* Loads the model and its sidecar. kind ("depth" / "disparity", NULL: sidecar or default)
 * overrides the output kind; size (0: none) and the frame size pick a dynamic model's input.
 * Fails naming the model (or the sidecar) on anything the runtime cannot run or a sidecar that
 * disagrees with the model. */
pg_status depth_net_open(const char *model_path, const char *kind, int size, int frame_width, int frame_height, depth_net **net);
void depth_net_close(depth_net *net); /* accepts NULL */
const depth_net_info *depth_net_get_info(const depth_net *net);

/* Depth (height, width) of one RGB frame (float, [0, 1]) on threads threads: the network's output
 * resampled once to the size asked for (box-filtered when shrinking). */
pg_status depth_net_infer(depth_net *net, const pg_image *frame, float *depth, int width, int height, int threads);

#endif
