/* The frame envelope: checksum, header texts, writing a whole frame. */
#include "topgimbal.h"

uint8_t tg_checksum(const uint8_t *p, size_t n) {
    unsigned s = 0;
    size_t k;
    for (k = 0; k < n; k++) s += p[k];
    return (uint8_t)s;
}

const char *tg_header_text(uint8_t header) {
    switch (header) {
    case TG_HDR_TP: return "#TP";
    case TG_HDR_tp: return "#tp";
    case TG_HDR_tP: return "#tP";
    case TG_HDR_Tp: return "#Tp";
    default: return NULL;
    }
}

const char *tg_status_text(int status) {
    switch (status) {
    case TG_OK: return "ok (TG_OK)";
    case TG_E_INVALID: return "bytes do not fit the field (TG_E_INVALID)";
    case TG_E_UNSURE: return "a spelling the C core does not decode (TG_E_UNSURE)";
    case TG_E_RANGE: return "value out of range (TG_E_RANGE)";
    case TG_E_TYPE: return "value of the wrong type for the field (TG_E_TYPE)";
    case TG_E_SPACE: return "output buffer too small (TG_E_SPACE)";
    case TG_E_UNKNOWN: return "identifier not in the dialect (TG_E_UNKNOWN)";
    case TG_E_NO_FORM: return "no form of the command fits the data (TG_E_NO_FORM)";
    case TG_E_ARG: return "bad argument: address, control, header or missing field (TG_E_ARG)";
    default: return status > 0 ? "a length, not an error" : "unknown status";
    }
}

static int is_addr(char c) { return c == 'U' || c == 'M' || c == 'D' || c == 'E' || c == 'P' || c == 'G'; }

static int is_ident(char c) {
    return (c >= '0' && c <= '9') || (c >= 'A' && c <= 'Z') || (c >= 'a' && c <= 'z');
}

static uint8_t hexdigit(unsigned v) { return (uint8_t)(v < 10 ? '0' + v : 'A' + v - 10); }

int tg_frame_write(const tg_frame *f, uint8_t *out, size_t cap) {
    const char *h = tg_header_text(f->header);
    size_t n = f->len, total = 12 + n, k;
    long wire_len = f->declared >= 0 ? f->declared : (long)n;
    uint8_t s;
    if (!h || !is_addr(f->src) || !is_addr(f->dst)) return TG_E_ARG;
    if (!is_ident(f->ident[0]) || !is_ident(f->ident[1]) || !is_ident(f->ident[2])) return TG_E_ARG;
    if (f->header == TG_HDR_Tp) {
        if (wire_len > 0xFFFF) return TG_E_RANGE;
    } else {
        if (f->rw != 'r' && f->rw != 'w') return TG_E_ARG;
        if (wire_len > (f->header == TG_HDR_tP ? 0xFF : 0x0F)) return TG_E_RANGE;
    }
    if (total > cap) return TG_E_SPACE;
    out[0] = '#';
    out[1] = (uint8_t)h[1];
    out[2] = (uint8_t)h[2];
    out[3] = (uint8_t)f->src;
    out[4] = (uint8_t)f->dst;
    if (f->header == TG_HDR_Tp) {
        out[5] = (uint8_t)(wire_len >> 8);
        out[6] = (uint8_t)(wire_len & 0xFF);
    } else {
        out[5] = f->header == TG_HDR_tP ? (uint8_t)wire_len : hexdigit((unsigned)wire_len);
        out[6] = (uint8_t)f->rw;
    }
    out[7] = (uint8_t)f->ident[0];
    out[8] = (uint8_t)f->ident[1];
    out[9] = (uint8_t)f->ident[2];
    if (n && out + 10 != f->data) memmove(out + 10, f->data, n);
    s = 0;
    for (k = 0; k < 10 + n; k++) s = (uint8_t)(s + out[k]);
    out[10 + n] = hexdigit(s >> 4);
    out[11 + n] = hexdigit(s & 15);
    return (int)total;
}
