/* fuzz_trainset.c - libFuzzer harness: scene_cameras_load (trainset.json / cameras.json) on any bytes. */
#include "fuzz_common.h"
#include "render/scene_cameras.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    static scene_cameras sc;
    scene_cameras_load(fuzz_file("trainset.json", data, size), &sc);
    return 0;
}
