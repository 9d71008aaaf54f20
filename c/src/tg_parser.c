/*
 * The streaming parser: a bounded buffer driven by tg_scan_step, fed a byte (or a chunk) at a
 * time. Between wake-up conditions reported by the scanner (a declared end not yet reached, no
 * '#' or line end arrived) a byte costs a comparison, so byte-at-a-time use from a UART interrupt
 * is cheap, and the result is the same as rescanning after every byte.
 */
#include "topgimbal.h"

void tg_parser_init(tg_parser *p, const tg_scan_cfg *cfg) {
    memset(p, 0, sizeof *p);
    if (cfg) {
        p->cfg = *cfg;
    } else {
        p->cfg.max_data = TG_PARSER_MAX_DATA;
        p->cfg.recover_length = 1;
    }
    if (p->cfg.max_data > TG_PARSER_MAX_DATA) p->cfg.max_data = TG_PARSER_MAX_DATA;
}

void tg_parser_reset(tg_parser *p) {
    p->len = p->pos = 0;
    p->idle = p->final = p->pending = 0;
}

size_t tg_parser_space(const tg_parser *p) { return sizeof p->buf - p->len; }

static void wake_check(tg_parser *p, const uint8_t *data, size_t n) {
    size_t k;
    if (!p->idle) return;
    if (p->len >= p->wake_len) {
        p->idle = 0;
        return;
    }
    if (p->wake_mark)
        for (k = 0; k < n; k++)
            if (data[k] == '#' || data[k] == '\r' || data[k] == '\n') {
                p->idle = 0;
                return;
            }
}

int tg_parser_push(tg_parser *p, uint8_t byte) {
    if (p->len >= sizeof p->buf) return 0;
    p->buf[p->len++] = byte;
    p->stats.bytes++;
    wake_check(p, &byte, 1);
    return 1;
}

size_t tg_parser_feed(tg_parser *p, const uint8_t *data, size_t n) {
    size_t room = sizeof p->buf - p->len;
    if (n > room) n = room;
    if (n == 0) return 0; /* a zero-length chunk may come with a NULL pointer */
    memcpy(p->buf + p->len, data, n);
    p->len += n;
    p->stats.bytes += (uint32_t)n;
    wake_check(p, data, n);
    return n;
}

void tg_parser_flush(tg_parser *p) {
    p->final = 1;
    p->final_len = p->len;
    p->idle = 0;
}

static size_t junk_count(const uint8_t *raw, size_t n) {
    size_t k, c = 0;
    for (k = 0; k < n; k++)
        if (raw[k] != '\r' && raw[k] != '\n') c++;
    return c;
}

static void frame_event(tg_parser *p, const tg_step *st, tg_event *ev) {
    memset(ev, 0, sizeof *ev);
    ev->type = TG_EV_FRAME;
    tg_step_frame(p->buf, st, &ev->frame);
    ev->raw = p->buf + st->start;
    ev->raw_len = st->end - st->start;
    p->stats.frames++;
}

static void diag_event(tg_event *ev, uint8_t diag, uint8_t reason, const uint8_t *raw, size_t n) {
    memset(ev, 0, sizeof *ev);
    ev->type = TG_EV_DIAG;
    ev->diag = diag;
    ev->reason = reason;
    ev->raw = raw;
    ev->raw_len = n;
}

/* Drop what was scanned, keep from `keep` on. */
static void compact(tg_parser *p, size_t keep) {
    if (keep > 0) {
        memmove(p->buf, p->buf + keep, p->len - keep);
        p->len -= keep;
    }
    p->pos = 0;
}

int tg_parser_next(tg_parser *p, tg_event *ev) {
    tg_step st;
    if (p->pending) {
        p->pending = 0;
        frame_event(p, &p->pending_step, ev);
        p->stats.length_recoveries++;
        return 1;
    }
    for (;;) {
        size_t end; /* the scan's end: the flush point while flushing */
        if (p->idle) return 0;
        if (p->final && p->pos >= p->final_len && p->final_len < p->len) {
            /* the flushed stream is resolved; what was fed after the flush starts a new one */
            p->final = 0;
            compact(p, p->pos);
        }
        if (p->pos >= p->len) {
            compact(p, p->len);
            p->final = 0;
            p->idle = 1;
            p->wake_len = 1;
            p->wake_mark = 0;
            return 0;
        }
        end = p->final ? p->final_len : p->len;
        tg_scan_step(p->buf, end, p->pos, p->final, &p->cfg, &st);
        switch (st.kind) {
        case TG_STEP_WAIT:
            if (p->final) {
                /* Flush: what is left cannot become a frame. */
                size_t start = st.next, left = end - start;
                size_t junk = junk_count(p->buf + start, left);
                p->pos = end;
                if (junk) {
                    p->stats.bytes_discarded += (uint32_t)junk;
                    p->stats.resyncs++;
                    diag_event(ev, TG_DIAG_GARBAGE, TG_R_END_OF_STREAM, p->buf + start, left);
                    return 1;
                }
                continue;
            }
            compact(p, st.next);
            p->wake_len = st.wake_len > st.next ? st.wake_len - st.next : 0;
            p->wake_mark = st.wake_mark;
            p->idle = 1;
            if (p->len >= sizeof p->buf) {
                /* Cannot happen within the bound (see TG_PARSER_BUF); never stall: resolve now. */
                p->final = 1;
                p->final_len = p->len;
                p->idle = 0;
            }
            return 0;
        case TG_STEP_FRAME:
            p->pos = st.next;
            frame_event(p, &st, ev);
            return 1;
        case TG_STEP_RECOVERED:
            p->pos = st.next;
            p->pending = 1;
            p->pending_step = st;
            diag_event(ev, TG_DIAG_LENGTH_MISMATCH, TG_R_LENGTH_MISMATCH, p->buf + st.start, st.end - st.start);
            return 1;
        case TG_STEP_BAD_CHECKSUM:
            p->pos = st.next;
            p->stats.bad_checksums++;
            p->stats.bytes_discarded += (uint32_t)(st.next - st.start);
            p->stats.resyncs++;
            diag_event(ev, TG_DIAG_BAD_CHECKSUM, TG_R_BAD_CHECKSUM, p->buf + st.start, st.end - st.start);
            return 1;
        default: { /* DISCARD */
            size_t n = st.end - st.start, junk = junk_count(p->buf + st.start, n);
            p->pos = st.next;
            if (st.reason == TG_R_OVERSIZE) p->stats.oversize++;
            if (!junk) continue;
            p->stats.bytes_discarded += (uint32_t)junk;
            p->stats.resyncs++;
            diag_event(ev, st.diag, st.reason, p->buf + st.start, n);
            return 1;
        }
        }
    }
}
