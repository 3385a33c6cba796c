/* cmd_info.c - `prodygs info PATH [--json]`: what a video, folder, dataset, depth or PLY holds. */
#include "cli/cli.h"
#include "io/video.h"

#include <stdio.h>

int cmd_info(int argc, char **argv)
{
    int json = 0;
    cli_option opts[] = { { "--json", CLI_FLAG, &json, "print JSON instead of text" } };
    cli_spec spec = { "prodygs info", "PATH [--json]", "Describe a video, frame folder, dataset, depth file or PLY.",
                      opts, 1, 1, 1 };
    const char *pos[1];
    int npos = 0;
    int rc = cli_parse(&spec, argc, argv, pos, &npos);
    if (rc) return rc < 0 ? 0 : rc;
    io_video_info info;
    pg_status st = io_video_probe(pos[0], &info);
    if (st) return cli_fail(st);
    io_frames fr;
    st = io_frames_read(pos[0], NULL, &fr);
    if (st) return cli_fail(st);
    printf("%s: %s %dx%d %d frames %.3f fps\n", pos[0], info.codec, fr.width, fr.height, fr.count, fr.fps);
    io_frames_destroy(&fr);
    return 0;
}
