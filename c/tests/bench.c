/*
 * Throughput of parse + decode on a recorded stream (bench/codec.py writes it: datagrams, each a
 * 2-byte big-endian length and the bytes). Prints frames/s for whole datagrams and byte at a time,
 * best of three. A benchmark prints; it asserts nothing.
 */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "tg_catalog.h"

static double now(void) {
    struct timespec ts;
    clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts); /* CPU time: the machine is shared */
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

static tg_parser parser;

/* As bench/codec.py decodes (decode_any): the likelier dialect first (TOPOTEK for its addresses
 * and streams, SkyDroid otherwise), the other when that one has no form for the frame. */
static int decode_any(const tg_frame *f, tg_message *m) {
    int topotek_first =
        f->src == 'D' || f->dst == 'P' || memcmp(f->ident, "GIA", 3) == 0 || memcmp(f->ident, "GPS", 3) == 0;
    const tg_dialect *first = topotek_first ? &tg_topotek : &tg_skydroid;
    if (tg_decode(first, f, m) == TG_OK) return 1;
    return tg_decode(topotek_first ? &tg_skydroid : &tg_topotek, f, m) == TG_OK;
}

static unsigned long run(const uint8_t *buf, size_t size, int bytewise, int decode, unsigned long *ok) {
    size_t i = 0;
    unsigned long frames = 0;
    tg_event ev;
    tg_message m;
    tg_parser_init(&parser, NULL);
    while (i + 2 <= size) {
        size_t n = ((size_t)buf[i] << 8) | buf[i + 1], k;
        const uint8_t *dg = buf + i + 2;
        i += 2 + n;
        if (bytewise) {
            for (k = 0; k < n; k++) {
                tg_parser_push(&parser, dg[k]);
                while (tg_parser_next(&parser, &ev))
                    if (ev.type == TG_EV_FRAME) {
                        frames++;
                        if (decode && decode_any(&ev.frame, &m)) (*ok)++;
                    }
            }
        } else {
            k = 0;
            while (k < n) {
                k += tg_parser_feed(&parser, dg + k, n - k);
                while (tg_parser_next(&parser, &ev))
                    if (ev.type == TG_EV_FRAME) {
                        frames++;
                        if (decode && decode_any(&ev.frame, &m)) (*ok)++;
                    }
            }
        }
        tg_parser_flush(&parser);
        while (tg_parser_next(&parser, &ev))
            if (ev.type == TG_EV_FRAME) {
                frames++;
                if (decode && decode_any(&ev.frame, &m)) (*ok)++;
            }
    }
    return frames;
}

int main(int argc, char **argv) {
    FILE *fp;
    uint8_t *buf;
    long size;
    int mode;
    static const char *labels[3] = {"C parse only (datagrams)", "C parse + decode (datagrams)",
                                    "C parse + decode (byte at a time)"};
    if (argc < 2 || argc > 3 || !(fp = fopen(argv[1], "rb"))) {
        fprintf(stderr, "usage: %s STREAM [MODE 0..2]\n", argv[0]);
        return 2;
    }
    fseek(fp, 0, SEEK_END);
    size = ftell(fp);
    fseek(fp, 0, SEEK_SET);
    buf = malloc((size_t)size);
    if (!buf || fread(buf, 1, (size_t)size, fp) != (size_t)size) return 2;
    fclose(fp);
    for (mode = 0; mode < 3; mode++) {
        double best = 0;
        if (argc == 3 && mode != atoi(argv[2])) continue;
        unsigned long frames = 0, ok = 0;
        int rep;
        for (rep = 0; rep < 5; rep++) {
            double t0 = now(), dt;
            ok = 0;
            frames = run(buf, (size_t)size, mode == 2, mode > 0, &ok);
            dt = now() - t0;
            if ((double)frames / dt > best) best = (double)frames / dt;
        }
        printf("%-36s %12.0f frames/s  (%lu frames, %lu decoded)\n", labels[mode], best, frames, ok);
    }
    free(buf);
    return 0;
}
