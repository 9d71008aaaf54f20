/*
 * A ctypes-friendly face of the streaming parser for the differential fuzzer (diff_fuzz.py):
 * feed bytes, get the events as the same text lines the vectors use.
 */
#include <stdio.h>

#include "topgimbal.h"

size_t shim_size(void) { return sizeof(tg_parser); }

void shim_init(tg_parser *p, unsigned recover_length, unsigned max_data) {
    tg_scan_cfg cfg;
    cfg.max_data = max_data;
    cfg.recover_length = (uint8_t)recover_length;
    tg_parser_init(p, &cfg);
}

static size_t put_hex(char *out, size_t cap, const uint8_t *p, size_t n) {
    size_t k, w = 0;
    if (!n) return (size_t)snprintf(out, cap, "-");
    for (k = 0; k < n && w + 3 < cap; k++) w += (size_t)snprintf(out + w, cap - w, "%02x", p[k]);
    return w;
}

/* Feed n bytes one at a time (bytewise) or as one chunk, drain; flush when final.
 * Writes one event per line; returns the number of characters written, -1 if out was too small. */
int shim_feed(tg_parser *p, const uint8_t *data, size_t n, int bytewise, int final, char *out, size_t cap) {
    size_t w = 0, i = 0;
    tg_event ev;
    int pass;
    for (pass = 0; pass < 2; pass++) {
        if (pass == 1) {
            if (!final) break;
            tg_parser_flush(p);
        }
        for (;;) {
            if (pass == 0 && i < n) {
                size_t k = bytewise ? (size_t)tg_parser_push(p, data[i]) : tg_parser_feed(p, data + i, n - i);
                if (k == 0) return -2; /* would not fit: the caller's chunk is too big */
                i += k;
            }
            while (tg_parser_next(p, &ev)) {
                if (cap - w < 2 * ev.raw_len + 64) return -1;
                if (ev.type == TG_EV_FRAME) {
                    const tg_frame *f = &ev.frame;
                    w += (size_t)snprintf(out + w, cap - w, "F %u %c%c%c %.3s ", f->header, f->src, f->dst,
                                          f->rw ? f->rw : '-', f->ident);
                    w += put_hex(out + w, cap - w, f->data, f->len);
                    if (f->declared >= 0)
                        w += (size_t)snprintf(out + w, cap - w, " %d\n", f->declared);
                    else
                        w += (size_t)snprintf(out + w, cap - w, " -\n");
                } else {
                    w += (size_t)snprintf(out + w, cap - w, "D %u ", ev.diag);
                    w += put_hex(out + w, cap - w, ev.raw, ev.raw_len);
                    w += (size_t)snprintf(out + w, cap - w, "\n");
                }
            }
            if (pass == 1 || i >= n) break;
        }
    }
    return (int)w;
}

void shim_stats(const tg_parser *p, uint32_t *out7) {
    out7[0] = p->stats.frames;
    out7[1] = p->stats.bytes;
    out7[2] = p->stats.bad_checksums;
    out7[3] = p->stats.resyncs;
    out7[4] = p->stats.bytes_discarded;
    out7[5] = p->stats.length_recoveries;
    out7[6] = p->stats.oversize;
}
