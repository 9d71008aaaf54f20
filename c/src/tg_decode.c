/* Messages: a frame's fields by the catalog (decode), and a request built from values (encode). */
#include "topgimbal.h"

uint32_t tg_ident_hash(const char ident[3]);

/* Shared with the generator (tools/cgen.py: ident_hash): Knuth's multiplicative hash. */
uint32_t tg_ident_hash(const char ident[3]) {
    uint32_t key = (uint32_t)(uint8_t)ident[0] | ((uint32_t)(uint8_t)ident[1] << 8) | ((uint32_t)(uint8_t)ident[2] << 16);
    return key * 2654435761u;
}

const tg_command *tg_command_find(const tg_dialect *d, const char ident[3]) {
    uint32_t mask = (uint32_t)d->hash_size - 1u, h = (tg_ident_hash(ident) >> 16) & mask;
    for (;;) {
        uint16_t slot = d->hash[h];
        const tg_command *c;
        if (!slot) return NULL;
        c = &d->commands[slot - 1];
        if (c->ident[0] == ident[0] && c->ident[1] == ident[1] && c->ident[2] == ident[2]) return c;
        h = (h + 1) & mask;
    }
}

const tg_form *tg_form_find(const tg_command *c, char rw, uint8_t direction, unsigned nth) {
    unsigned k;
    for (k = 0; k < c->n_forms; k++) {
        const tg_form *f = &c->forms[k];
        if (f->rw == rw && f->direction == direction) {
            if (nth == 0) return f;
            nth--;
        }
    }
    return NULL;
}

int tg_form_decode(const tg_form *form, const uint8_t *data, size_t len, tg_value *values) {
    static const uint8_t empty[1] = {0};
    unsigned k;
    int result = TG_OK;
    if (len == 0) data = empty; /* no data may come as a NULL pointer (a frame without data) */
    if (form->const_data) {
        return (len == form->const_len && memcmp(data, form->const_data, len) == 0) ? TG_OK : TG_E_INVALID;
    }
    if (len < form->min_len || len > form->max_len) return TG_E_INVALID;
    for (k = 0; k < form->n_fields; k++) {
        const tg_field *f = &form->fields[k];
        size_t w = f->codec->width ? f->codec->width : len - f->offset;
        int r = tg_codec_decode(f->codec, data + f->offset, w, &values[k]);
        if (r == TG_E_INVALID) return TG_E_INVALID;
        if (r != TG_OK) result = r;
    }
    return result;
}

static int is_device(char a) { return a == 'M' || a == 'D' || a == 'E' || a == 'G'; }
static int is_host(char a) { return a == 'U' || a == 'P'; }

int tg_decode(const tg_dialect *d, const tg_frame *f, tg_message *m) {
    const tg_command *c = tg_command_find(d, f->ident);
    uint8_t direction = (is_device(f->src) && is_host(f->dst)) ? TG_RESPONSE : TG_REQUEST;
    int w = f->rw != 'r';
    unsigned k;
    m->cmd = c;
    m->form = NULL;
    m->n_fields = 0;
    if (!c) return TG_E_UNKNOWN;
    for (k = 0; k < c->n_order[w][direction]; k++) {
        const tg_form *form = &c->forms[c->order[w][direction][k]];
        if (f->len < form->min_len || f->len > form->max_len) continue;
        if (tg_form_decode(form, f->data, f->len, m->values) == TG_OK) {
            m->form = form;
            m->n_fields = form->n_fields;
            return TG_OK;
        }
    }
    return TG_E_NO_FORM;
}

int tg_form_encode(const tg_form *form, const tg_value *values, uint8_t *out, size_t cap) {
    uint8_t nowhere; /* out may be NULL when cap is 0: `out + n` then points here (never written) */
    size_t n = 0;
    unsigned k;
    if (!out) {
        out = &nowhere;
        cap = 0;
    }
    if (form->const_data) {
        if (form->const_len > cap) return TG_E_SPACE;
        memcpy(out, form->const_data, form->const_len);
        return form->const_len;
    }
    for (k = 0; k < form->n_fields; k++) {
        const tg_field *f = &form->fields[k];
        const tg_value *v = &values[k];
        int r;
        if (v->type == TG_V_ABSENT) {
            if (!f->has_default) return TG_E_ARG;
            if (f->def_len > cap - n) return TG_E_SPACE;
            memcpy(out + n, f->def_raw, f->def_len);
            n += f->def_len;
            continue;
        }
        r = tg_codec_encode(f->codec, v, out + n, cap - n);
        if (r < 0) return r;
        n += (size_t)r;
    }
    return (int)n;
}

uint8_t tg_header_for(const tg_dialect *d, const tg_command *c, size_t n, char dst) {
    if (c && c->header != TG_HDR_NONE) {
        size_t max = c->header == TG_HDR_tP ? 0xFF : (c->header == TG_HDR_Tp ? 0xFFFF : 0x0F);
        if (n <= max) return c->header;
    }
    if (d->gimbal_header != TG_HDR_NONE && (dst == 'G' || (c && c->address == 'G')) && n <= 15) return d->gimbal_header;
    if (n == 2) return TG_HDR_TP;
    if (n <= 0x0F) return TG_HDR_tp;
    if (n <= 0xFF && (d->headers & (1u << TG_HDR_tP))) return TG_HDR_tP;
    if (d->headers & (1u << TG_HDR_Tp)) return TG_HDR_Tp;
    return TG_HDR_NONE;
}

int tg_encode(const tg_dialect *d, const tg_command *c, const tg_form *form, char src, char dst, uint8_t header,
              const tg_value *values, uint8_t *out, size_t cap) {
    tg_frame f;
    int n;
    if (cap < 12) return TG_E_SPACE;
    n = tg_form_encode(form, values, out + 10, cap - 12);
    if (n < 0) return n;
    if (!header) header = tg_header_for(d, c, (size_t)n, dst);
    if (!header) return TG_E_RANGE;
    if (header == TG_HDR_Tp && form->rw != 'w') return TG_E_ARG;
    f.header = header;
    f.src = src;
    f.dst = dst;
    f.rw = header == TG_HDR_Tp ? 0 : form->rw;
    memcpy(f.ident, c->ident, 3);
    f.data = out + 10;
    f.len = (uint16_t)n;
    f.declared = -1;
    return tg_frame_write(&f, out, cap);
}
