/*
 * libFuzzer harness (ASan + UBSan): random bytes through the streaming parser in random chunks,
 * then every frame through the decoders of both dialects and back through the encoder.
 * Properties: no crash or undefined behaviour; bytes are accounted for; every frame the parser
 * delivers can be written again (tg_frame_write accepts exactly what the scanner accepts) and
 * scans as the same frame; a decoded message re-encodes to data that decodes to the same values.
 *
 * Input: byte 0 picks the chunk size, bit 0 of byte 1 turns length recovery off (the parser's one
 * option); the rest is the stream. Inputs that once failed live in fuzz/regressions/ and run on
 * every `make -C c test` (and from pytest).
 */
#include <stdlib.h>
#include <string.h>

#include "tg_catalog.h"

static void check(int ok) {
    if (!ok) abort();
}

static void check_frame(const tg_event *ev) {
    static const tg_dialect *const dialects[2] = {&tg_skydroid, &tg_topotek};
    /* A good frame after the one written: a frame recovered from a wrong length character ended
     * where the next frame began, and alone it would wait for the bytes its length promises. */
    static const uint8_t next[] = "#TPUD2wCAP013E";
    uint8_t out[TG_FRAME_MAX + 16 + sizeof next], data[TG_FRAME_MAX];
    tg_frame f = ev->frame, g;
    tg_scan_cfg cfg = {TG_PARSER_MAX_DATA, 1};
    tg_step st;
    tg_message m, m2;
    int n, k, d;
    n = tg_frame_write(&f, out, sizeof out - (sizeof next - 1));
    check(n == (int)ev->raw_len);
    memcpy(out + n, next, sizeof next - 1);
    tg_scan_step(out, (size_t)n + sizeof next - 1, 0, 1, &cfg, &st);
    check(st.kind == TG_STEP_FRAME || st.kind == TG_STEP_RECOVERED);
    check(st.start == 0 && st.end == (size_t)n);
    tg_step_frame(out, &st, &g);
    check(g.len == f.len && memcmp(g.data, f.data, f.len) == 0 && memcmp(g.ident, f.ident, 3) == 0);
    for (d = 0; d < 2; d++) {
        if (tg_decode(dialects[d], &f, &m) != TG_OK) continue;
        n = tg_form_encode(m.form, m.values, data, sizeof data);
        if (n < 0) continue; /* decoding checks no ranges; encoding does */
        check(tg_form_decode(m.form, data, (size_t)n, m2.values) == TG_OK);
        for (k = 0; k < m.n_fields; k++) {
            int64_t x;
            check(m.values[k].type == m2.values[k].type);
            if (m.values[k].type == TG_V_NUM) {
                check(tg_value_rescale(&m2.values[k], m.values[k].exp10, &x) == TG_OK);
                check(x == m.values[k].num);
            }
        }
    }
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size) {
    static tg_parser p;
    tg_event ev;
    size_t i = 0, chunk, frame_bytes = 0;
    uint32_t seen_frames = 0;
    if (size < 2) return 0;
    chunk = (size_t)data[0] % 40 + 1;
    tg_parser_init(&p, NULL);
    if (data[1] & 1) p.cfg.recover_length = 0;
    data += 2;
    size -= 2;
    while (i < size) {
        size_t n = size - i < chunk ? size - i : chunk;
        n = tg_parser_feed(&p, data + i, n);
        i += n;
        if (data[i - 1] == 0x7F) tg_parser_flush(&p);
        while (tg_parser_next(&p, &ev)) {
            if (ev.type == TG_EV_FRAME) {
                check_frame(&ev);
                frame_bytes += ev.raw_len;
                seen_frames++;
            }
        }
        check(p.len <= sizeof p.buf);
    }
    tg_parser_flush(&p);
    while (tg_parser_next(&p, &ev))
        if (ev.type == TG_EV_FRAME) {
            check_frame(&ev);
            frame_bytes += ev.raw_len;
            seen_frames++;
        }
    check(p.len == 0);
    check(p.stats.frames == seen_frames);
    check(p.stats.bytes == size);
    check(frame_bytes + p.stats.bytes_discarded <= size);
    return 0;
}
