/* fuzz_video.c - libFuzzer harness: io_video_probe (FFmpeg demuxer + our checks) on any bytes. */
#include "fuzz_common.h"
#include "io/video.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    io_video_info info;
    io_video_probe(fuzz_file("x.mp4", data, size), &info);
    return 0;
}
