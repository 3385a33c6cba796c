"""ctypes copies of the structs of include/prodygs.h, field for field and in the same order.

Edit this file together with the header: the module compares every struct's size with the
library's own (pg_struct_size) when it loads, and python/tests/test_layout.py compiles a C
program against the header that checks the offset of every field listed here.
"""
import ctypes as C

CAMERA_LABEL = 160    # PG_CAMERA_LABEL
CAMERA_LABELS = 2048  # PG_CAMERA_LABELS

_s = C.c_char_p
_i = C.c_int
_f = C.c_float
_d = C.c_double


def _label(n):
    return C.c_char * n


class DepthConfig(C.Structure):
    _c_name = "pg_depth_config"
    _fields_ = [("input", _s), ("model", _s), ("out", _s), ("train_camera", _s), ("kind", _s),
                ("size", _i), ("out_width", _i), ("out_height", _i), ("frames", _i),
                ("threads", _i), ("stop_after", _i)]


class DepthReport(C.Structure):
    _c_name = "pg_depth_report"
    _fields_ = [("train_camera", _label(CAMERA_LABEL)), ("model_name", _label(128)), ("kind", _label(16)),
                ("frames", _i), ("computed", _i), ("reused", _i), ("width", _i), ("height", _i),
                ("model_width", _i), ("model_height", _i), ("threads", _i),
                ("decode_width", _i), ("decode_height", _i), ("finished", _i), ("skipped", _i),
                ("seconds", _d), ("ms_per_frame", _d)]


class PrepareConfig(C.Structure):
    _c_name = "pg_prepare_config"
    _fields_ = [("input", _s), ("depth", _s), ("depth_model", _s), ("out", _s), ("train_camera", _s),
                ("depth_kind", _s), ("depth_scale", _f), ("refine", _s),
                ("align", _i), ("fuse", _i), ("planes", _i), ("ground", _i), ("fov", _f), ("movers_front", _i),
                ("frames", _i), ("width", _i), ("height", _i), ("threads", _i), ("keep_flow_vis", _i)]


class PrepareReport(C.Structure):
    _c_name = "pg_prepare_report"
    _fields_ = [("train_camera", _label(CAMERA_LABEL)),
                ("frames", _i), ("width", _i), ("height", _i), ("reference", _i), ("fallback_frames", _i),
                ("threads", _i), ("residual_before", _d), ("residual_after", _d), ("seconds", _d)]


class ProxiesConfig(C.Structure):
    _c_name = "pg_proxies_config"
    _fields_ = [("input", _s), ("depth", _s), ("out", _s), ("train_camera", _s), ("test_cameras", _s),
                ("poses", _s), ("proxies", _i), ("max_angle", _f), ("fov", _f), ("pad", _f),
                ("pose_scale", _f), ("depth_unit", _d), ("render", _s), ("fit_steps", _i),
                ("fit_block", _i), ("frames", _i), ("width", _i), ("height", _i), ("threads", _i),
                ("force", _i), ("diagnose", _i), ("pose_shift", _i)]


class ProxiesReport(C.Structure):
    _c_name = "pg_proxies_report"
    _fields_ = [("train_camera", _label(CAMERA_LABEL)), ("test_cameras", _label(CAMERA_LABELS)),
                ("poses", _label(16)), ("frames", _i), ("computed", _i), ("reused", _i), ("proxies", _i),
                ("threads", _i), ("pose_scale_fitted", _i), ("pose_scale", _d), ("pose_scale_cost", _d),
                ("mean_valid_fraction", _d), ("seconds", _d), ("mean_source_psnr", _d),
                ("diagnosed_views", _i), ("diagnose_psnr_reprojected", _d), ("diagnose_psnr_guessed", _d),
                ("diagnose_psnr_moving", _d), ("pose_shift", _d), ("pose_fit", _label(160))]


class TrainConfig(C.Structure):
    _c_name = "pg_train_config"
    _fields_ = [("input", _s), ("out", _s), ("iters", _i), ("coarse_iters", _i), ("densify_until", _i),
                ("resume", _i), ("threads", _i), ("seed", _i), ("max_gaussians", _i), ("init_points", _i),
                ("checkpoint_every", _i), ("sh_degree", _i), ("proxies", _i),
                ("real_cameras", _s), ("test_cameras", _s), ("depth", _s), ("frames", _i), ("width", _i),
                ("views_per_step", _i), ("times_per_step", _i), ("motion_crops", _i),
                ("real_weight", _f), ("moving_weight", _f), ("lambda_depth", _f), ("lambda_dssim", _f),
                ("proxy_moving_weight", _f), ("deform_res", _i), ("deform_width", _i),
                ("static_check_every", _i), ("deform_head_width", _i), ("deform_tres", _i),
                ("deform_time_coarsen", _i), ("deform_time_warmup", _f), ("densify_movable", _f),
                ("proxy_downscale", _i), ("use_static", _i), ("use_cull", _i), ("eval_train", _i),
                ("stop_at_iter", _i), ("full_size_input", _s), ("full_size_camera", _s),
                ("full_size_steps", _i)]


class TrainReport(C.Structure):
    _c_name = "pg_train_report"
    _fields_ = [("iterations", _i), ("gaussians", _i), ("static_gaussians", _i), ("threads", _i),
                ("seed", _i), ("finished", _i), ("test_psnr", _d), ("train_psnr", _d),
                ("train_psnr_moving", _d), ("train_psnr_static", _d), ("seconds", _d),
                ("full_width", _i), ("full_height", _i), ("full_still_added", _i), ("full_psnr", _d),
                ("full_psnr_moving", _d), ("full_psnr_static", _d), ("full_seconds", _d),
                ("full_psnr_before", _d), ("full_psnr_moving_before", _d)]


class EvaluateConfig(C.Structure):
    _c_name = "pg_evaluate_config"
    _fields_ = [("dataset", _s), ("model", _s), ("out", _s), ("config_json", _s), ("stages_json", _s),
                ("threads", _i), ("trainset", _s)]


class EvaluateReport(C.Structure):
    _c_name = "pg_evaluate_report"
    _fields_ = [("frames", _i), ("psnr", _d), ("ssim", _d), ("psnr_moving", _d), ("train_psnr_moving", _d),
                ("train_psnr_static", _d), ("seconds", _d), ("flat_psnr", _d), ("as_is_psnr", _d),
                ("warp_psnr", _d), ("warp_psnr_moving", _d)]


class RenderConfig(C.Structure):
    _c_name = "pg_render_config"
    _fields_ = [("model", _s), ("out", _s), ("path", _s), ("camera", _s), ("name", _s),
                ("reference_frames", _s), ("steps", _i), ("angle", _f), ("yaw", _f), ("pitch", _f),
                ("time", _f), ("fps", _f), ("write_depth", _i), ("write_frames", _i), ("threads", _i),
                ("camera_path", _s), ("width", _i), ("height", _i)]


class RenderReport(C.Structure):
    _c_name = "pg_render_report"
    _fields_ = [("frames", _i), ("fallback_png", _i), ("seconds", _d)]


class ExportConfig(C.Structure):
    _c_name = "pg_export_config"
    _fields_ = [("model", _s), ("out", _s), ("times", C.POINTER(C.c_float)), ("num_times", _i),
                ("frames", C.POINTER(C.c_int)), ("num_frames", _i), ("all_frames", _i), ("format", _s)]


class ExportReport(C.Structure):
    _c_name = "pg_export_report"
    _fields_ = [("files", _i), ("gaussians", _i), ("dropped", _i), ("cameras", _i)]


class ViewConfig(C.Structure):
    _c_name = "pg_view_config"
    _fields_ = [("model", _s), ("out", _s), ("frames", _i), ("max_gaussians", _i)]


class ViewReport(C.Structure):
    _c_name = "pg_view_report"
    _fields_ = [("static_gaussians", _i), ("moving_gaussians", _i), ("dropped", _i), ("frames", _i),
                ("sh_degree", _i), ("scene_bytes", _d), ("bytes_per_second", _d), ("seconds", _d)]


PIPELINE_STAGES = ("prepare", "proxies", "train", "evaluate", "render", "depth")  # order of ran[] / seconds[]


class PipelineReport(C.Structure):
    _c_name = "pg_pipeline_report"
    _fields_ = [("train_camera", _label(CAMERA_LABEL)), ("test_cameras", _label(CAMERA_LABELS)),
                ("width", _i), ("height", _i), ("iters", _i), ("proxies", _i), ("threads", _i),
                ("ran", _i * 6), ("seconds", _d * 6), ("train", TrainReport), ("evaluation", EvaluateReport),
                ("seconds_total", _d), ("peak_rss_kb", C.c_long), ("disk_mib", _d), ("started", _i)]


PLAN_CALLBACK = C.CFUNCTYPE(None, C.POINTER(PipelineReport), C.c_void_p)


class PipelineConfig(C.Structure):
    _c_name = "pg_pipeline_config"
    _fields_ = [("input", _s), ("depth", _s), ("out", _s), ("depth_model", _s), ("preset", _s),
                ("train_camera", _s), ("test_cameras", _s), ("poses", _s), ("proxies", _i),
                ("max_angle", _f), ("fov", _f), ("pad", _f), ("pose_scale", _f), ("proxy_render", _s),
                ("depth_kind", _s), ("depth_scale", _f), ("refine", _i), ("align", _i), ("fuse", _i),
                ("planes", _i), ("ground", _i), ("movers_front", _i), ("pose_shift", _i), ("frames", _i), ("width", _i), ("height", _i),
                ("iters", _i), ("deform_width", _i), ("deform_head_width", _i), ("deform_time_coarsen", _i),
                ("deform_time_warmup", _f), ("densify_movable", _f), ("densify_until", _i),
                ("proxy_downscale", _i), ("motion_crops", _i), ("views_per_step", _i),
                ("proxy_moving_weight", _f), ("real_weight", _f), ("sh_degree", _i), ("threads", _i),
                ("seed", _i), ("evaluate", _i), ("render_videos", _i), ("render_width", _i),
                ("render_height", _i), ("command", _s), ("on_plan", PLAN_CALLBACK), ("user", C.c_void_p)]


ALL = (DepthConfig, DepthReport, PrepareConfig, PrepareReport, ProxiesConfig, ProxiesReport, TrainConfig,
       TrainReport, EvaluateConfig, EvaluateReport, RenderConfig, RenderReport, ExportConfig, ExportReport,
       ViewConfig, ViewReport, PipelineConfig, PipelineReport)
