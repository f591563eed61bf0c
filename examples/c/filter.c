/*
 * filter.c: the quadtex C API in one program. Packs (or opens) a texture,
 * filters a few pixel footprints, prints their colours and checks them.
 *
 *   filter               packs samples/threshold.svg at level 10 (run from
 *                        the repository root) and checks colours of the art
 *   filter TEXTURE.qtx   opens a packed texture; checks what holds for any
 *
 * Exits 0 when every check passes, 1 otherwise. Build and run it with
 * examples/c/run.sh.
 */
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "quadtex.h"

static int failures = 0;

static void check(int ok, const char *what) {
    printf("  [%s] %s\n", ok ? "ok" : "FAILED", what);
    if (!ok) {
        failures++;
    }
}

/* The last error of this thread, never NULL (qtx_last_error() is NULL
 * after a call that succeeded). */
static const char *error_message(void) {
    const char *message = qtx_last_error();
    return message ? message : "(no message)";
}

static void print_rgba(const char *name, const float rgba[4]) {
    printf("%-34s r %.5f  g %.5f  b %.5f  a %.5f\n", name, rgba[0], rgba[1], rgba[2], rgba[3]);
}

static int near(const float got[4], const float want[4], float tolerance) {
    for (int i = 0; i < 4; i++) {
        if (!(fabsf(got[i] - want[i]) <= tolerance)) {
            return 0;
        }
    }
    return 1;
}

/* A colour a texture can hold: premultiplied, 0 <= r, g, b <= a <= 1. */
static int plausible(const float c[4]) {
    const float eps = 1e-5f;
    for (int i = 0; i < 3; i++) {
        if (!(c[i] >= -eps && c[i] <= c[3] + eps)) {
            return 0;
        }
    }
    return c[3] >= -eps && c[3] <= 1.0f + eps;
}

/* An sRGB-encoded 8-bit channel in linear light, as the packer decodes it. */
static float srgb8_to_linear(unsigned v) {
    double c = v / 255.0;
    return (float)(c <= 0.04045 ? c / 12.92 : pow((c + 0.055) / 1.055, 2.4));
}

int main(int argc, char **argv) {
    const int sample = argc < 2;
    QtxTexture *texture = NULL;
    QtxStatus status = sample ? qtx_pack("samples/threshold.svg", 0.0, 10, 0, &texture)
                              : qtx_open(argv[1], &texture);
    if (status != QTX_STATUS_OK) {
        fprintf(stderr, "filter: %s (status %d)\n", qtx_last_error(), (int)status);
        return 1;
    }
    QtxTextureInfo info;
    if (qtx_texture_info(texture, &info) != QTX_STATUS_OK) {
        fprintf(stderr, "filter: %s\n", error_message());
        qtx_free(texture);
        return 1;
    }
    printf("%s: depth %u, %llu nodes, %llu bytes\n", sample ? "samples/threshold.svg" : argv[1],
           (unsigned)info.depth, (unsigned long long)info.node_count,
           (unsigned long long)info.memory_bytes);
    print_rgba("mean colour", info.mean);

    /* Footprints: the texture-space images of a pixel's corners (0,0),
     * (1,0), (1,1), (0,1), as x, z pairs (texture z is up, screen y down). */
    const double quads[4][8] = {
        /* Axis-aligned, in the grass left of the runway (x < 21/90). */
        {0.02, 0.90, 0.20, 0.90, 0.20, 0.10, 0.02, 0.10},
        /* Projective (a pixel seeing a receding plane), in the grass too. */
        {0.01, 0.85, 0.21, 0.85, 0.15, 0.15, 0.07, 0.15},
        /* Projective, across the runway's threshold markings. */
        {0.20, 0.30, 0.80, 0.30, 0.95, 0.02, 0.05, 0.02},
        /* Sixteen by sixteen tiles of the repeating texture. */
        {-8.0, 8.0, 8.0, 8.0, 8.0, -8.0, -8.0, -8.0},
    };
    float rgba[4][4];
    QtxFilterOptions options = qtx_filter_options_default();
    options.wrap_x = options.wrap_z = QTX_WRAP_MODE_REPEAT;
    if (qtx_filter(texture, &quads[0][0], 4, &options, &rgba[0][0]) != QTX_STATUS_OK) {
        fprintf(stderr, "filter: %s\n", error_message());
        qtx_free(texture);
        return 1;
    }
    print_rgba("axis-aligned", rgba[0]);
    print_rgba("projective", rgba[1]);
    print_rgba("projective, larger", rgba[2]);
    print_rgba("16 x 16 tiles", rgba[3]);

    /* The same footprint weighted uniformly in texture space instead of
     * over the pixel (the two differ for a projective footprint). */
    float by_area[4];
    options.weighting = QTX_WEIGHTING_TEXTURE;
    status = qtx_filter(texture, quads[2], 1, &options, by_area);
    options.weighting = QTX_WEIGHTING_SCREEN;
    check(status == QTX_STATUS_OK, "texture-space weighting accepted");
    print_rgba("  ...weighted in texture space", by_area);

    /* Border wrap: a footprint beyond the unit square sees the border colour. */
    const double outside[8] = {2.0, 3.0, 3.0, 3.0, 3.0, 2.0, 2.0, 2.0};
    const float border[4] = {0.1f, 0.2f, 0.3f, 0.5f};
    QtxFilterOptions bordered = options;
    bordered.wrap_x = bordered.wrap_z = QTX_WRAP_MODE_BORDER;
    memcpy(bordered.border, border, sizeof border);
    float beyond[4];
    status = qtx_filter(texture, outside, 1, &bordered, beyond);
    print_rgba("beyond the square, border wrap", beyond);

    printf("checks:\n");
    check(status == QTX_STATUS_OK && near(beyond, border, 1e-6f), "border wrap shows the border colour");
    check(near(rgba[3], info.mean, 1e-4f), "many whole tiles average to the texture's mean");
    for (int i = 0; i < 4; i++) {
        char what[64];
        snprintf(what, sizeof what, "colour %d is premultiplied and within [0, 1]", i);
        check(plausible(rgba[i]), what);
    }
    if (sample) {
        /* Grass, #4a6b34, opaque. */
        const float grass[4] = {srgb8_to_linear(0x4a), srgb8_to_linear(0x6b),
                                srgb8_to_linear(0x34), 1.0f};
        check(near(rgba[0], grass, 1e-3f), "axis-aligned footprint in the grass is grass");
        check(near(rgba[1], grass, 1e-3f), "projective footprint in the grass is grass");
        check(fabsf(rgba[2][3] - 1.0f) < 1e-4f && !near(rgba[2], grass, 1e-2f),
              "footprint across the markings is opaque and not grass");
    }

    /* Errors: a NaN corner (quad 1, corner 2, z) refuses the whole call,
     * names the quad and the field, and leaves the output untouched. */
    double bad[2][8];
    memcpy(bad[0], quads[0], sizeof bad[0]);
    memcpy(bad[1], quads[1], sizeof bad[1]);
    bad[1][2 * 2 + 1] = NAN;
    float untouched[2][4] = {{-1.0f, -1.0f, -1.0f, -1.0f}, {-1.0f, -1.0f, -1.0f, -1.0f}};
    status = qtx_filter(texture, &bad[0][0], 2, NULL, &untouched[0][0]);
    printf("NaN corner: status %d, \"%s\"\n", (int)status, error_message());
    check(status == QTX_STATUS_INVALID_ARGUMENT, "a NaN corner is an invalid argument");
    check(qtx_last_error() != NULL && strstr(qtx_last_error(), "quad 1") != NULL &&
              strstr(qtx_last_error(), "corner[2].z") != NULL,
          "the message names the quad and the corner");
    check(untouched[0][0] == -1.0f && untouched[1][3] == -1.0f, "nothing was written");

    QtxFilterOptions sloppy = qtx_filter_options_default();
    sloppy.error_bound = 0.0;
    status = qtx_filter(texture, quads[0], 1, &sloppy, rgba[0]);
    printf("error bound 0: status %d, \"%s\"\n", (int)status, error_message());
    check(status == QTX_STATUS_INVALID_ARGUMENT && strstr(error_message(), "error bound") != NULL,
          "an option out of range is refused by name");

    QtxTexture *missing = NULL;
    status = qtx_open("no/such/texture.qtx", &missing);
    printf("missing file: status %d, \"%s\"\n", (int)status, error_message());
    check(status == QTX_STATUS_IO && missing == NULL &&
              strstr(error_message(), "no/such/texture.qtx") != NULL,
          "a missing file is an I/O error naming the file");

    status = qtx_filter(NULL, quads[0], 1, NULL, rgba[0]);
    check(status == QTX_STATUS_INVALID_ARGUMENT, "a NULL texture is refused");
    status = qtx_filter(texture, NULL, 0, NULL, NULL);
    check(status == QTX_STATUS_OK && qtx_last_error() == NULL,
          "no footprints, no buffers: fine, and the error is cleared");

    qtx_free(texture);
    qtx_free(NULL);
    if (failures) {
        printf("%d check(s) failed\n", failures);
        return 1;
    }
    printf("all checks passed\n");
    return 0;
}
