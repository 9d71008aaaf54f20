/*
 * topgimbal._speedups._ctop: the Python fast path, built from libtopgimbal's own sources
 * (c/src/tg_scan.c, c/src/tg_codec.c).
 *
 * ParserMethod: FrameParser.feed / feed_datagram / flush / feed_messages in one C call each: the
 *            scanner runs over the bytes, good frames become Frame objects here, and every rare
 *            event (diagnostics, recovered frames) goes to the parser's own Python helper
 *            (`_c_event`), so diagnostics and statistics are the pure parser's by construction.
 *            With a decoder of this module as `decode`, frames become Messages in the same call.
 * Decoder:   Dialect.decode for the forms the C codecs handle natively; fields of other codecs go
 *            to their Python codec, and any frame the C core is not sure about goes to the pure
 *            decoder whole, so results are identical to the pure path.
 * AnyDecoder: decode_any (the preferred dialect, then the others in guess_dialects' order), with
 *            the pure decode_any for every frame no dialect decodes natively.
 * recv_many: (Linux) up to RECV_MANY_MAX datagrams of a non-blocking IPv4 UDP socket in one
 *            recvmmsg call, for the shared socket of a fleet server (transport/udp_shared.py).
 */
#define PY_SSIZE_T_CLEAN
#include <Python.h>

#include "topgimbal.h"

#define ABI_VERSION 3

static PyObject *headers[5]; /* "#TP" ... by tg_header code */
static PyObject *s_buf, *s_stats, *s_bytes, *s_frames, *s_max_data, *s_recover, *s_c_event, *s_final, *s_decode;

/* ---- frames ------------------------------------------------------------------------------- */

/* Identifiers repeat: one str object per identifier (a bounded cache), which also keeps their
 * hashes for the catalog's dictionary lookups. */
#define IDENT_SLOTS 1024
static struct {
    uint32_t key;
    PyObject *str;
} ident_cache[IDENT_SLOTS];

static uint32_t ident_key(const unsigned char *p) {
    return (uint32_t)p[0] | ((uint32_t)p[1] << 8) | ((uint32_t)p[2] << 16);
}

static PyObject *ident_str(const char *p) {
    uint32_t key = ident_key((const unsigned char *)p), slot = (key * 2654435761u) >> 22;
    PyObject *s;
    if (ident_cache[slot].str && ident_cache[slot].key == key) {
        Py_INCREF(ident_cache[slot].str);
        return ident_cache[slot].str;
    }
    s = PyUnicode_DecodeLatin1(p, 3, NULL);
    if (!s) return NULL;
    Py_XSETREF(ident_cache[slot].str, s);
    ident_cache[slot].key = key;
    Py_INCREF(s);
    return s;
}

static PyObject *new_tuple_of(PyTypeObject *cls, Py_ssize_t n) {
    /* A NamedTuple instance is a plain tuple of its type: what tuple.__new__(cls, items) builds. */
    return cls->tp_alloc(cls, n);
}

static PyObject *make_frame(PyTypeObject *frame_cls, const uint8_t *buf, const tg_step *st) {
    tg_frame f;
    PyObject *obj, *ident, *data, *rw, *declared;
    tg_step_frame(buf, st, &f);
    ident = ident_str(f.ident);
    data = PyBytes_FromStringAndSize((const char *)f.data, f.len);
    rw = f.rw ? PyUnicode_FromOrdinal((unsigned char)f.rw) : PyUnicode_FromStringAndSize("", 0);
    declared = f.declared >= 0 ? PyLong_FromLong(f.declared) : (Py_INCREF(Py_None), Py_None);
    obj = new_tuple_of(frame_cls, 7);
    if (!ident || !data || !rw || !declared || !obj) {
        Py_XDECREF(ident);
        Py_XDECREF(data);
        Py_XDECREF(rw);
        Py_XDECREF(declared);
        Py_XDECREF(obj);
        return NULL;
    }
    Py_INCREF(headers[f.header]);
    PyTuple_SET_ITEM(obj, 0, headers[f.header]);
    PyTuple_SET_ITEM(obj, 1, PyUnicode_FromOrdinal((unsigned char)f.src)); /* latin-1 singletons */
    PyTuple_SET_ITEM(obj, 2, PyUnicode_FromOrdinal((unsigned char)f.dst));
    PyTuple_SET_ITEM(obj, 3, rw);
    PyTuple_SET_ITEM(obj, 4, ident);
    PyTuple_SET_ITEM(obj, 5, data);
    PyTuple_SET_ITEM(obj, 6, declared);
    if (!PyTuple_GET_ITEM(obj, 1) || !PyTuple_GET_ITEM(obj, 2)) {
        Py_DECREF(obj);
        return NULL;
    }
    return obj;
}

/* ---- decoder ------------------------------------------------------------------------------ */

typedef struct {
    PyObject *name;     /* field name (str) */
    PyObject *pycodec;  /* the Python codec, when this field is delegated to it */
    PyObject *names;    /* enum value names (tuple of str), or NULL */
    PyObject *literal;  /* literal text (str), or NULL */
    tg_codec *codec;    /* native codec, NULL when delegated */
    Py_ssize_t offset, width; /* width 0: the rest of the data */
} dfield;

typedef struct {
    PyObject *form;       /* the catalog Form */
    PyObject *const_data; /* bytes or NULL */
    Py_ssize_t min_len, max_len, n_fields;
    dfield *fields;
} dform;

typedef struct {
    uint32_t key; /* 3 identifier bytes, 0 = empty slot */
    PyObject *spec;
    Py_ssize_t n_forms;
    dform *forms;
    uint8_t *order[2][2];
    Py_ssize_t n_order[2][2];
} dcommand;

typedef struct {
    PyObject_HEAD
    vectorcallfunc vectorcall;
    PyObject *message_cls;
    PyObject *fallback;
    PyObject *name;     /* the dialect's name (Message.dialect) */
    PyObject *keep;     /* objects whose memory the tables point into */
    unsigned headers;   /* bit (1 << tg_header) per header of the dialect */
    unsigned hosts;     /* bit 1: U, bit 2: P among its host addresses */
    Py_ssize_t n_slots; /* power of two */
    dcommand *slots;
} Decoder;

static PyTypeObject DecoderType;

static uint32_t slot_of(uint32_t key, Py_ssize_t n_slots) { return ((key * 2654435761u) >> 16) & (uint32_t)(n_slots - 1); }

static void free_codec(tg_codec *c) {
    if (!c) return;
    PyMem_Free((void *)c->raws);
    PyMem_Free((void *)c->spellings);
    PyMem_Free((void *)c->none_tokens);
    free_codec((tg_codec *)c->sub);
    PyMem_Free(c);
}

static void free_command(dcommand *c) {
    Py_ssize_t f, k;
    int a, b;
    for (f = 0; f < c->n_forms && c->forms; f++) {
        if (c->forms[f].fields)
            for (k = 0; k < c->forms[f].n_fields; k++) free_codec(c->forms[f].fields[k].codec);
        PyMem_Free(c->forms[f].fields);
    }
    PyMem_Free(c->forms);
    for (a = 0; a < 2; a++)
        for (b = 0; b < 2; b++) PyMem_Free(c->order[a][b]);
}

static void free_tables(Decoder *self) {
    Py_ssize_t s;
    if (self->slots) {
        for (s = 0; s < self->n_slots; s++)
            if (self->slots[s].key) free_command(&self->slots[s]);
        PyMem_Free(self->slots);
    }
    self->slots = NULL;
    self->n_slots = 0;
}

static void Decoder_dealloc(Decoder *self) {
    free_tables(self);
    Py_XDECREF(self->message_cls);
    Py_XDECREF(self->fallback);
    Py_XDECREF(self->name);
    Py_XDECREF(self->keep);
    Py_TYPE(self)->tp_free((PyObject *)self);
}

/* Keep `obj` alive for the decoder's lifetime; returns it (borrowed). */
static PyObject *keep(Decoder *d, PyObject *obj) {
    if (!obj || PyList_Append(d->keep, obj) < 0) return NULL;
    return obj;
}

static const char *bytes_str(Decoder *d, PyObject *b) {
    if (!PyBytes_Check(b) || !keep(d, b)) {
        if (!PyErr_Occurred()) PyErr_SetString(PyExc_TypeError, "expected bytes");
        return NULL;
    }
    return PyBytes_AS_STRING(b); /* NUL-terminated */
}

/* A codec descriptor tuple from spec.py (codec_tuple there) -> tg_codec. */
static tg_codec *build_codec(Decoder *d, PyObject *t) {
    tg_codec *c;
    PyObject *raws, *spell, *nones, *text, *sub;
    int exp10;
    long mul;
    long long lo, hi;
    Py_ssize_t k;
    c = PyMem_Calloc(1, sizeof *c);
    if (!c) return (tg_codec *)PyErr_NoMemory();
    /* "b" stores straight into the uint8_t members and refuses what does not fit in 0..255 */
    if (!PyArg_ParseTuple(t, "bbbbbbbbbibblLLOOOOO", &c->kind, &c->width, &c->min_width, &c->max_width,
                          &c->is_signed, &c->little, &c->lat, &c->binary, &c->pyfloat, &exp10, &c->decimals,
                          &c->pad, &mul, &lo, &hi, &raws, &spell, &nones, &text, &sub)) {
        PyMem_Free(c);
        return NULL;
    }
    if (exp10 < INT8_MIN || exp10 > INT8_MAX || mul < INT32_MIN || mul > INT32_MAX) {
        PyMem_Free(c);
        PyErr_SetString(PyExc_OverflowError, "codec descriptor: exp10 or mul out of range");
        return NULL;
    }
    c->exp10 = (int8_t)exp10;
    c->mul = (int32_t)mul;
    c->lo = lo;
    c->hi = hi;
    if (!PyTuple_Check(raws) || !PyTuple_Check(spell) || !PyTuple_Check(nones)) goto bad;
    c->n_values = (uint8_t)PyTuple_GET_SIZE(raws);
    c->n_spellings = (uint8_t)PyTuple_GET_SIZE(spell);
    c->n_none = (uint8_t)PyTuple_GET_SIZE(nones);
    if (c->n_values) {
        const char **r = PyMem_Calloc((size_t)c->n_values, sizeof *r);
        if (!(c->raws = r)) goto bad;
        for (k = 0; k < c->n_values; k++)
            if (!(r[k] = bytes_str(d, PyTuple_GET_ITEM(raws, k)))) goto bad;
    }
    if (c->n_spellings) {
        tg_spelling *s = PyMem_Calloc((size_t)c->n_spellings, sizeof *s);
        if (!(c->spellings = s)) goto bad;
        for (k = 0; k < c->n_spellings; k++) {
            PyObject *pair = PyTuple_GET_ITEM(spell, k);
            if (!PyTuple_Check(pair) || PyTuple_GET_SIZE(pair) != 2) goto bad;
            if (!(s[k].raw = bytes_str(d, PyTuple_GET_ITEM(pair, 0)))) goto bad;
            s[k].value = (uint8_t)PyLong_AsLong(PyTuple_GET_ITEM(pair, 1));
        }
    }
    if (c->n_none) {
        const char **n = PyMem_Calloc((size_t)c->n_none, sizeof *n);
        if (!(c->none_tokens = n)) goto bad;
        for (k = 0; k < c->n_none; k++)
            if (!(n[k] = bytes_str(d, PyTuple_GET_ITEM(nones, k)))) goto bad;
    }
    if (PyBytes_Check(text) && PyBytes_GET_SIZE(text) && !(c->text = bytes_str(d, text))) goto bad;
    if (sub != Py_None && !(c->sub = build_codec(d, sub))) goto bad;
    return c;
bad:
    free_codec(c);
    if (!PyErr_Occurred()) PyErr_SetString(PyExc_ValueError, "bad codec descriptor");
    return NULL;
}

static int build_form(Decoder *d, PyObject *t, dform *f) {
    PyObject *fields;
    Py_ssize_t k;
    if (!PyArg_ParseTuple(t, "OOnnO", &f->form, &f->const_data, &f->min_len, &f->max_len, &fields)) return -1;
    if (f->min_len < 0 || f->max_len < f->min_len)
        return PyErr_SetString(PyExc_ValueError, "form lengths must be 0 <= min_len <= max_len"), -1;
    if (!keep(d, f->form)) return -1;
    if (f->const_data == Py_None) {
        f->const_data = NULL;
    } else if (!PyBytes_Check(f->const_data) || !keep(d, f->const_data)) {
        PyErr_SetString(PyExc_TypeError, "const data must be bytes or None");
        return -1;
    }
    if (!PyTuple_Check(fields)) return PyErr_SetString(PyExc_TypeError, "fields must be a tuple"), -1;
    f->n_fields = PyTuple_GET_SIZE(fields);
    f->fields = PyMem_Calloc((size_t)(f->n_fields ? f->n_fields : 1), sizeof *f->fields);
    if (!f->fields) return PyErr_NoMemory(), -1;
    for (k = 0; k < f->n_fields; k++) {
        dfield *x = &f->fields[k];
        PyObject *desc, *names, *literal;
        if (!PyArg_ParseTuple(PyTuple_GET_ITEM(fields, k), "OnnOOOO", &x->name, &x->offset, &x->width, &desc,
                              &x->pycodec, &names, &literal))
            return -1;
        if (!keep(d, x->name) || !keep(d, x->pycodec)) return -1;
        x->names = names == Py_None ? NULL : keep(d, names);
        x->literal = literal == Py_None ? NULL : keep(d, literal);
        if (desc != Py_None && !(x->codec = build_codec(d, desc))) return -1;
        /* decode_form reads data[offset, offset + width) of data at least min_len long, and
         * py_value indexes names by the codec's value: a layout that breaks either is refused */
        if (x->offset < 0 || x->width < 0 || x->offset + x->width > f->min_len ||
            (x->codec && x->codec->n_values &&
             (!x->names || !PyTuple_Check(x->names) || PyTuple_GET_SIZE(x->names) < x->codec->n_values)))
            return PyErr_SetString(PyExc_ValueError, "field layout does not fit the form"), -1;
    }
    return 0;
}

static int build_command(Decoder *d, PyObject *t, dcommand *c) {
    PyObject *ident, *forms, *orders;
    Py_ssize_t k;
    int a, b;
    if (!PyArg_ParseTuple(t, "OOO!O", &ident, &c->spec, &PyTuple_Type, &forms, &orders)) return -1;
    if (!PyBytes_Check(ident) || PyBytes_GET_SIZE(ident) != 3)
        return PyErr_SetString(PyExc_ValueError, "identifier must be 3 bytes"), -1;
    if (!keep(d, c->spec)) return -1;
    c->key = ident_key((const unsigned char *)PyBytes_AS_STRING(ident));
    c->n_forms = PyTuple_GET_SIZE(forms);
    c->forms = PyMem_Calloc((size_t)(c->n_forms ? c->n_forms : 1), sizeof *c->forms);
    if (!c->forms) return PyErr_NoMemory(), -1;
    for (k = 0; k < c->n_forms; k++)
        if (build_form(d, PyTuple_GET_ITEM(forms, k), &c->forms[k]) < 0) return -1;
    if (!PyTuple_Check(orders) || PyTuple_GET_SIZE(orders) != 2) goto bad_order;
    for (a = 0; a < 2; a++) {
        PyObject *pair = PyTuple_GET_ITEM(orders, a);
        if (!PyTuple_Check(pair) || PyTuple_GET_SIZE(pair) != 2) goto bad_order;
        for (b = 0; b < 2; b++) {
            PyObject *o = PyTuple_GET_ITEM(pair, b);
            Py_ssize_t n, i;
            if (!PyTuple_Check(o)) goto bad_order;
            n = PyTuple_GET_SIZE(o);
            c->n_order[a][b] = n;
            c->order[a][b] = PyMem_Calloc((size_t)(n ? n : 1), 1);
            if (!c->order[a][b]) return PyErr_NoMemory(), -1;
            for (i = 0; i < n; i++) {
                long v = PyLong_AsLong(PyTuple_GET_ITEM(o, i));
                if (v == -1 && PyErr_Occurred()) return -1;
                if (v < 0 || v >= c->n_forms || v > 255) goto bad_order;
                c->order[a][b][i] = (uint8_t)v;
            }
        }
    }
    return 0;
bad_order:
    PyErr_SetString(PyExc_ValueError, "decode orders must be ((r_req, r_rsp), (w_req, w_rsp)) of form indices");
    return -1;
}

static int header_code_of(PyObject *h) {
    int k;
    for (k = 1; k < 5; k++)
        if (h == headers[k]) return k;
    if (!PyUnicode_Check(h)) return 0;
    for (k = 1; k < 5; k++)
        if (PyUnicode_Compare(h, headers[k]) == 0) return k;
    if (PyErr_Occurred()) PyErr_Clear();
    return 0;
}

/* Decoder(commands, message_cls, fallback, name, headers, host_addresses); commands: tuple of
 * (ident bytes, spec, forms, ((r_req, r_rsp), (w_req, w_rsp))) from spec.decoder_tables. */
static int Decoder_init(Decoder *self, PyObject *args, PyObject *kw) {
    PyObject *commands, *hdrs, *message_cls, *fallback, *name;
    const char *hosts;
    Py_ssize_t n, k;
    (void)kw;
    if (self->slots) return PyErr_SetString(PyExc_TypeError, "a Decoder is built once"), -1;
    if (!PyArg_ParseTuple(args, "O!OOUO!s", &PyTuple_Type, &commands, &message_cls, &fallback, &name, &PyTuple_Type,
                          &hdrs, &hosts))
        return -1;
    if (!PyType_Check(message_cls) || !PyType_IsSubtype((PyTypeObject *)message_cls, &PyTuple_Type))
        return PyErr_SetString(PyExc_TypeError, "message_cls must be a tuple subclass"), -1;
    /* XSETREF: __init__ may run again after a failed one; the tables stay NULL until all is built */
    Py_INCREF(message_cls);
    Py_XSETREF(self->message_cls, message_cls);
    Py_INCREF(fallback);
    Py_XSETREF(self->fallback, fallback);
    Py_INCREF(name);
    Py_XSETREF(self->name, name);
    self->headers = 0;
    for (k = 0; k < PyTuple_GET_SIZE(hdrs); k++) self->headers |= 1u << header_code_of(PyTuple_GET_ITEM(hdrs, k));
    self->headers &= ~1u;
    self->hosts = (strchr(hosts, 'U') ? 1u : 0u) | (strchr(hosts, 'P') ? 2u : 0u);
    Py_XSETREF(self->keep, PyList_New(0));
    if (!self->keep) return -1;
    n = PyTuple_GET_SIZE(commands);
    self->n_slots = 8;
    while (self->n_slots < 2 * n) self->n_slots *= 2;
    self->slots = PyMem_Calloc((size_t)self->n_slots, sizeof *self->slots);
    if (!self->slots) return PyErr_NoMemory(), -1;
    for (k = 0; k < n; k++) {
        dcommand tmp;
        uint32_t s;
        memset(&tmp, 0, sizeof tmp);
        if (build_command(self, PyTuple_GET_ITEM(commands, k), &tmp) < 0 || !tmp.key) {
            free_command(&tmp);
            free_tables(self); /* half a catalog would decode some frames: none instead */
            if (!PyErr_Occurred()) PyErr_SetString(PyExc_ValueError, "identifier must not be 3 NUL bytes");
            return -1;
        }
        s = slot_of(tmp.key, self->n_slots);
        while (self->slots[s].key) s = (s + 1) & (uint32_t)(self->n_slots - 1);
        self->slots[s] = tmp;
    }
    return 0;
}

/* A Decoder made by Decoder.__new__ alone, or whose __init__ failed, has no tables: every use is a
 * TypeError rather than a read through a NULL table. */
static int ready(const Decoder *d) {
    if (d->slots) return 1;
    PyErr_SetString(PyExc_TypeError, "Decoder is not initialised: build it with Decoder(commands, ...)");
    return 0;
}

static const dcommand *lookup(const Decoder *d, uint32_t key) {
    uint32_t s = slot_of(key, d->n_slots);
    while (d->slots[s].key) {
        if (d->slots[s].key == key) return &d->slots[s];
        s = (s + 1) & (uint32_t)(d->n_slots - 1);
    }
    return NULL;
}

static const double POW10D[10] = {1e0, 1e1, 1e2, 1e3, 1e4, 1e5, 1e6, 1e7, 1e8, 1e9};

static PyObject *hex_str(const uint8_t *p, Py_ssize_t n) {
    static const char digits[] = "0123456789abcdef";
    PyObject *s = PyUnicode_New(2 * n, 127);
    Py_UCS1 *out;
    Py_ssize_t k;
    if (!s) return NULL;
    out = PyUnicode_1BYTE_DATA(s);
    for (k = 0; k < n; k++) {
        out[2 * k] = (Py_UCS1)digits[p[k] >> 4];
        out[2 * k + 1] = (Py_UCS1)digits[p[k] & 15];
    }
    return s;
}

/* The Python value of a natively decoded field (new reference). */
static PyObject *py_value(const dfield *f, const tg_codec *c, const tg_value *v) {
    switch (v->type) {
    case TG_V_NULL: Py_RETURN_NONE;
    case TG_V_ENUM: {
        PyObject *name = PyTuple_GET_ITEM(f->names, v->num);
        Py_INCREF(name);
        return name;
    }
    case TG_V_NUM: {
        int pyfloat = c->pyfloat;
        if (c->kind == TG_K_ONEOF && c->sub) pyfloat = c->sub->pyfloat;
        if (!pyfloat) return PyLong_FromLongLong(v->num);
        /* the decimal's nearest double, as Python's division by an exact power of ten / round() */
        if (v->exp10 < 0) return PyFloat_FromDouble((double)v->num / POW10D[-v->exp10]);
        return PyFloat_FromDouble((double)v->num * POW10D[v->exp10]);
    }
    case TG_V_TEXT:
        if (f->literal) {
            Py_INCREF(f->literal);
            return f->literal;
        }
        return PyUnicode_DecodeLatin1((const char *)v->ptr, v->len, NULL);
    case TG_V_BYTES: return hex_str(v->ptr, v->len);
    default: PyErr_SetString(PyExc_RuntimeError, "unexpected value type"); return NULL;
    }
}

enum { FORM_OK = 0, FORM_FAIL = 1, FORM_UNSURE = 2, FORM_ERROR = -1 };

static int decode_form(const dform *form, const uint8_t *data, Py_ssize_t len, PyObject *data_obj, PyObject **out) {
    PyObject *dict;
    Py_ssize_t k;
    if (form->const_data) {
        if (len != PyBytes_GET_SIZE(form->const_data) || memcmp(data, PyBytes_AS_STRING(form->const_data), (size_t)len))
            return FORM_FAIL;
        *out = PyDict_New();
        return *out ? FORM_OK : FORM_ERROR;
    }
    dict = PyDict_New();
    if (!dict) return FORM_ERROR;
    for (k = 0; k < form->n_fields; k++) {
        const dfield *f = &form->fields[k];
        Py_ssize_t w = f->width ? f->width : len - f->offset;
        PyObject *value;
        if (f->codec) {
            tg_value v;
            int r = tg_codec_decode(f->codec, data + f->offset, (size_t)w, &v);
            if (r != TG_OK) {
                Py_DECREF(dict);
                return r == TG_E_INVALID ? FORM_FAIL : FORM_UNSURE;
            }
            value = py_value(f, f->codec, &v);
        } else {
            PyObject *slice = (f->offset == 0 && w == len) ? (Py_INCREF(data_obj), data_obj)
                                                            : PyBytes_FromStringAndSize((const char *)data + f->offset, w);
            if (!slice) {
                Py_DECREF(dict);
                return FORM_ERROR;
            }
            value = PyObject_CallMethodOneArg(f->pycodec, s_decode, slice);
            Py_DECREF(slice);
            if (!value && PyErr_ExceptionMatches(PyExc_ValueError)) { /* UnicodeDecodeError included */
                PyErr_Clear();
                Py_DECREF(dict);
                return FORM_FAIL;
            }
        }
        if (!value || PyDict_SetItem(dict, f->name, value) < 0) {
            Py_XDECREF(value);
            Py_DECREF(dict);
            return FORM_ERROR;
        }
        Py_DECREF(value);
    }
    *out = dict;
    return FORM_OK;
}

/* Address letter of a one-character str, 0 otherwise. */
static Py_UCS4 one_char(PyObject *s) {
    if (!PyUnicode_Check(s) || PyUnicode_GET_LENGTH(s) != 1) return 0;
    return PyUnicode_READ_CHAR(s, 0);
}

static int is_device(Py_UCS4 a) { return a == 'M' || a == 'D' || a == 'E' || a == 'G'; }
static int is_host(Py_UCS4 a) { return a == 'U' || a == 'P'; }

static PyObject *message(const Decoder *d, PyObject *frame, PyObject *spec, PyObject *form, PyObject *fields,
                         PyObject *error) {
    PyObject *msg = new_tuple_of((PyTypeObject *)d->message_cls, 6);
    if (!msg) {
        Py_XDECREF(fields);
        Py_XDECREF(error);
        return NULL;
    }
    Py_INCREF(frame);
    Py_INCREF(spec);
    Py_INCREF(form);
    Py_INCREF(d->name);
    if (!fields) fields = (Py_INCREF(Py_None), Py_None);
    if (!error) error = (Py_INCREF(Py_None), Py_None);
    PyTuple_SET_ITEM(msg, 0, frame);
    PyTuple_SET_ITEM(msg, 1, spec);
    PyTuple_SET_ITEM(msg, 2, form);
    PyTuple_SET_ITEM(msg, 3, fields);
    PyTuple_SET_ITEM(msg, 4, error);
    PyTuple_SET_ITEM(msg, 5, d->name);
    return msg;
}

/* Dialect.decode's words when no form takes the data's length (the common failure: a frame
 * given to the other dialect). */
static PyObject *length_error(const dcommand *c, int w, int dir, Py_ssize_t len, const char *ident) {
    PyObject *parts = PyList_New(0), *sep, *joined, *err;
    Py_ssize_t k;
    if (!parts) return NULL;
    for (k = 0; k < c->n_order[w][dir]; k++) {
        const dform *f = &c->forms[c->order[w][dir][k]];
        PyObject *t = f->max_len != f->min_len ? PyUnicode_FromFormat("%zd..%zd", f->min_len, f->max_len)
                                               : PyUnicode_FromFormat("%zd", f->min_len);
        if (!t || PyList_Append(parts, t) < 0) {
            Py_XDECREF(t);
            Py_DECREF(parts);
            return NULL;
        }
        Py_DECREF(t);
    }
    sep = PyUnicode_FromString(" or ");
    joined = sep ? PyUnicode_Join(sep, parts) : NULL;
    Py_XDECREF(sep);
    Py_DECREF(parts);
    if (!joined) return NULL;
    err = PyUnicode_FromFormat("%zd data bytes; %.3s (%c) takes %U", len, ident, w ? 'w' : 'r', joined);
    Py_DECREF(joined);
    return err;
}

/* What the C core makes of a frame for one dialect. */
enum { NATIVE_ERROR = -1, NATIVE_OK = 0, NATIVE_NO_FORM, NATIVE_BY_LENGTH, NATIVE_UNSURE };

typedef struct {
    PyObject *ident, *data;
    Py_UCS4 src, dst;
    int w;       /* 0 r, 1 w */
    uint32_t key;
} frame_view;

/* The parts of a Frame the decoder reads; 0 when it is not a frame the C core can judge (then the
 * pure decoder answers). */
static int view_of(PyObject *frame, frame_view *v) {
    PyObject *rw;
    Py_UCS4 c;
    if (!PyTuple_Check(frame) || PyTuple_GET_SIZE(frame) < 6) return 0;
    v->ident = PyTuple_GET_ITEM(frame, 4);
    v->data = PyTuple_GET_ITEM(frame, 5);
    rw = PyTuple_GET_ITEM(frame, 3);
    if (!PyUnicode_Check(v->ident) || PyUnicode_GET_LENGTH(v->ident) != 3 ||
        PyUnicode_KIND(v->ident) != PyUnicode_1BYTE_KIND || !PyBytes_Check(v->data) || !PyUnicode_Check(rw))
        return 0;
    v->src = one_char(PyTuple_GET_ITEM(frame, 1));
    v->dst = one_char(PyTuple_GET_ITEM(frame, 2));
    if (!v->src || !v->dst) return 0;
    if (PyUnicode_GET_LENGTH(rw) == 0) {
        v->w = 1; /* #Tp: no control character, decoded as a write */
    } else {
        c = one_char(rw);
        if (c != 'r' && c != 'w') return 0;
        v->w = c == 'w';
    }
    v->key = ident_key(PyUnicode_1BYTE_DATA(v->ident));
    return 1;
}

static int decode_native(const Decoder *d, PyObject *frame, const frame_view *v, PyObject **msg) {
    const dcommand *c = lookup(d, v->key);
    PyObject *fields = NULL;
    const uint8_t *data;
    int dir, tried = 0;
    Py_ssize_t k, len;
    if (!c) return NATIVE_NO_FORM;
    dir = is_device(v->src) && is_host(v->dst);
    len = PyBytes_GET_SIZE(v->data);
    data = (const uint8_t *)PyBytes_AS_STRING(v->data);
    for (k = 0; k < c->n_order[v->w][dir]; k++) {
        const dform *form = &c->forms[c->order[v->w][dir][k]];
        int r;
        if (len < form->min_len || len > form->max_len) continue;
        tried = 1;
        r = decode_form(form, data, len, v->data, &fields);
        if (r == FORM_ERROR) return NATIVE_ERROR;
        if (r == FORM_UNSURE) return NATIVE_UNSURE;
        if (r == FORM_OK) {
            *msg = message(d, frame, c->spec, form->form, fields, NULL);
            return *msg ? NATIVE_OK : NATIVE_ERROR;
        }
    }
    return tried || c->n_order[v->w][dir] == 0 ? NATIVE_NO_FORM : NATIVE_BY_LENGTH;
}

static PyObject *decoder_decode(Decoder *self, PyObject *frame) {
    frame_view v;
    PyObject *msg = NULL;
    int r;
    if (!ready(self)) return NULL;
    if (!view_of(frame, &v)) return PyObject_CallOneArg(self->fallback, frame);
    r = decode_native(self, frame, &v, &msg);
    if (r == NATIVE_OK || r == NATIVE_ERROR) return msg;
    if (r == NATIVE_BY_LENGTH) { /* the pure decoder's words, without the trip */
        const dcommand *c = lookup(self, v.key);
        int dir = is_device(v.src) && is_host(v.dst);
        PyObject *err = length_error(c, v.w, dir, PyBytes_GET_SIZE(v.data), (const char *)PyUnicode_1BYTE_DATA(v.ident));
        if (!err) return NULL;
        return message(self, frame, c->spec, Py_None, NULL, err);
    }
    /* Unknown identifier, content no form takes (the pure decoder words the error), or a spelling
     * only Python reads: the pure decoder answers. */
    return PyObject_CallOneArg(self->fallback, frame);
}

/* Whether a decoder's call got what it takes, one frame and no keywords (else a TypeError). */
static int one_frame(size_t nargsf, PyObject *kwnames) {
    if (PyVectorcall_NARGS(nargsf) == 1 && !(kwnames && PyTuple_GET_SIZE(kwnames))) return 1;
    PyErr_SetString(PyExc_TypeError, "decode(frame) takes one frame");
    return 0;
}

static PyObject *Decoder_vectorcall(PyObject *self, PyObject *const *args, size_t nargsf, PyObject *kwnames) {
    return one_frame(nargsf, kwnames) ? decoder_decode((Decoder *)self, args[0]) : NULL;
}

static PyObject *Decoder_new(PyTypeObject *type, PyObject *args, PyObject *kw) {
    Decoder *self = (Decoder *)PyType_GenericNew(type, args, kw);
    if (self) self->vectorcall = Decoder_vectorcall;
    return (PyObject *)self;
}

static PyObject *Decoder_decode_many(Decoder *self, PyObject *frames) {
    PyObject *seq, *out;
    Py_ssize_t n, k;
    if (!ready(self)) return NULL;
    seq = PySequence_Fast(frames, "frames must be a sequence");
    if (!seq) return NULL;
    n = PySequence_Fast_GET_SIZE(seq);
    out = PyList_New(n);
    if (!out) {
        Py_DECREF(seq);
        return NULL;
    }
    for (k = 0; k < n; k++) {
        PyObject *m = decoder_decode(self, PySequence_Fast_GET_ITEM(seq, k));
        if (!m) {
            Py_DECREF(out);
            Py_DECREF(seq);
            return NULL;
        }
        PyList_SET_ITEM(out, k, m);
    }
    Py_DECREF(seq);
    return out;
}

static PyObject *Decoder_get_name(Decoder *self, void *closure) {
    (void)closure;
    if (!ready(self)) return NULL;
    Py_INCREF(self->name);
    return self->name;
}

static PyMethodDef Decoder_methods[] = {
    {"decode_many", (PyCFunction)Decoder_decode_many, METH_O, "Decode a sequence of frames -> list of Message."},
    {NULL, NULL, 0, NULL}};

static PyGetSetDef Decoder_getset[] = {{"dialect", (getter)Decoder_get_name, NULL, "the dialect's name", NULL},
                                       {NULL, NULL, NULL, NULL, NULL}};

/* ---- decoding across dialects ------------------------------------------------------------- */

#define MAX_CANDIDATES 8

typedef struct {
    PyObject_HEAD
    vectorcallfunc vectorcall;
    Decoder *prefer;                       /* tried first, or NULL */
    Decoder *cands[MAX_CANDIDATES];        /* the default dialects, in their default order */
    int excluded[MAX_CANDIDATES];          /* same name as `prefer`: not tried again */
    Py_ssize_t n;
    PyObject *fallback;                    /* the pure decode_any with the same preference */
} AnyDecoder;

static PyTypeObject AnyDecoderType;

static void AnyDecoder_dealloc(AnyDecoder *self) {
    Py_ssize_t k;
    Py_XDECREF(self->prefer);
    for (k = 0; k < self->n; k++) Py_XDECREF(self->cands[k]);
    Py_XDECREF(self->fallback);
    Py_TYPE(self)->tp_free((PyObject *)self);
}

static PyObject *any_decode(AnyDecoder *self, PyObject *frame);

static PyObject *AnyDecoder_vectorcall(PyObject *self, PyObject *const *args, size_t nargsf, PyObject *kwnames) {
    return one_frame(nargsf, kwnames) ? any_decode((AnyDecoder *)self, args[0]) : NULL;
}

/* AnyDecoder(prefer: Decoder | None, candidates: tuple[Decoder, ...], fallback) */
static PyObject *AnyDecoder_new(PyTypeObject *type, PyObject *args, PyObject *kw) {
    PyObject *prefer, *cands, *fallback;
    AnyDecoder *self;
    Py_ssize_t k;
    (void)kw;
    if (!PyArg_ParseTuple(args, "OO!O", &prefer, &PyTuple_Type, &cands, &fallback)) return NULL;
    if ((prefer != Py_None && !PyObject_TypeCheck(prefer, &DecoderType)) || PyTuple_GET_SIZE(cands) > MAX_CANDIDATES)
        return PyErr_Format(PyExc_TypeError, "AnyDecoder(prefer Decoder or None, up to %d Decoders, fallback)",
                            MAX_CANDIDATES);
    if (prefer != Py_None && !ready((Decoder *)prefer)) return NULL;
    self = (AnyDecoder *)type->tp_alloc(type, 0);
    if (!self) return NULL;
    self->vectorcall = AnyDecoder_vectorcall;
    if (prefer != Py_None) {
        Py_INCREF(prefer);
        self->prefer = (Decoder *)prefer;
    }
    for (k = 0; k < PyTuple_GET_SIZE(cands); k++) {
        PyObject *c = PyTuple_GET_ITEM(cands, k);
        if (!PyObject_TypeCheck(c, &DecoderType)) {
            Py_DECREF(self);
            return PyErr_Format(PyExc_TypeError, "candidates must be Decoders");
        }
        if (!ready((Decoder *)c)) {
            Py_DECREF(self);
            return NULL;
        }
        Py_INCREF(c);
        self->cands[self->n++] = (Decoder *)c;
        if (self->prefer) {
            int same = PyUnicode_Compare(self->prefer->name, ((Decoder *)c)->name);
            if (same == -1 && PyErr_Occurred()) {
                Py_DECREF(self);
                return NULL;
            }
            self->excluded[k] = same == 0;
        }
    }
    Py_INCREF(fallback);
    self->fallback = fallback;
    return (PyObject *)self;
}

/* guess_dialects' score: the identifier in the catalog (4), the header among the dialect's (2),
 * the frame's host side among its host addresses (1). */
static int guess_score(const Decoder *d, PyObject *frame, const frame_view *v) {
    unsigned host = (v->src == 'U' || v->dst == 'U' ? 1u : 0u) | (v->src == 'P' || v->dst == 'P' ? 2u : 0u);
    int hdr = header_code_of(PyTuple_GET_ITEM(frame, 0));
    return (lookup(d, v->key) != NULL) * 4 + ((d->headers >> hdr) & 1u) * 2 + (host && (host & ~d->hosts) == 0);
}

static PyObject *any_decode(AnyDecoder *self, PyObject *frame) {
    frame_view v;
    PyObject *msg = NULL;
    Decoder *order[MAX_CANDIDATES + 1];
    int score[MAX_CANDIDATES];
    Py_ssize_t n = 0, k, j;
    int r;
    if (!view_of(frame, &v)) return PyObject_CallOneArg(self->fallback, frame);
    if (self->prefer) order[n++] = self->prefer;
    for (k = 0; k < self->n; k++) { /* stable insertion by descending score */
        int s;
        if (self->excluded[k]) continue;
        s = guess_score(self->cands[k], frame, &v);
        j = n;
        while (j > (self->prefer ? 1 : 0) && score[j - 1] < s) {
            order[j] = order[j - 1];
            score[j] = score[j - 1];
            j--;
        }
        order[j] = self->cands[k];
        score[j] = s;
        n++;
    }
    for (k = 0; k < n; k++) {
        r = decode_native(order[k], frame, &v, &msg);
        if (r == NATIVE_OK || r == NATIVE_ERROR) return msg;
        if (r == NATIVE_UNSURE) break;
    }
    /* No dialect decodes it natively (the pure path words every reason), or one is unsure. */
    return PyObject_CallOneArg(self->fallback, frame);
}

/* ---- the parser --------------------------------------------------------------------------- */

static int only_separators(const uint8_t *p, size_t n) {
    size_t k;
    for (k = 0; k < n; k++)
        if (p[k] != '\r' && p[k] != '\n') return 0;
    return 1;
}

/* A rare event: the parser's own _c_event(buf, out, code, start, end, next, frame) words it. */
static int rare_event(PyObject *parser, PyObject *buf, PyObject *out, int code, const tg_step *st, PyObject *frame) {
    PyObject *args = Py_BuildValue("(OOinnnO)", buf, out, code, (Py_ssize_t)st->start, (Py_ssize_t)st->end,
                                   (Py_ssize_t)st->next, frame ? frame : Py_None);
    PyObject *meth = args ? PyObject_GetAttr(parser, s_c_event) : NULL, *r;
    r = meth ? PyObject_Call(meth, args, NULL) : NULL;
    Py_XDECREF(meth);
    Py_XDECREF(args);
    Py_XDECREF(r);
    return r ? 0 : -1;
}

/* Scan buf from pos; frames and rare events go to out in wire order. Returns where scanning
 * stopped (waiting for bytes), -1 on error; *nframes counts the good frames appended here. */
static Py_ssize_t scan_into(PyObject *parser, PyObject *buf, Py_ssize_t pos, int final, const tg_scan_cfg *cfg,
                            PyTypeObject *frame_cls, PyObject *out, Py_ssize_t *nframes) {
    const uint8_t *p = (const uint8_t *)PyBytes_AS_STRING(buf);
    size_t n = (size_t)PyBytes_GET_SIZE(buf);
    tg_step st;
    for (;;) {
        PyObject *item = NULL;
        tg_scan_step(p, n, (size_t)pos, final, cfg, &st);
        switch (st.kind) {
        case TG_STEP_WAIT: return (Py_ssize_t)st.next;
        case TG_STEP_FRAME:
            item = make_frame(frame_cls, p, &st);
            if (!item || PyList_Append(out, item) < 0) {
                Py_XDECREF(item);
                return -1;
            }
            Py_DECREF(item);
            (*nframes)++;
            break;
        case TG_STEP_RECOVERED:
            item = make_frame(frame_cls, p, &st);
            if (!item || rare_event(parser, buf, out, TG_R_LENGTH_MISMATCH, &st, item) < 0) {
                Py_XDECREF(item);
                return -1;
            }
            Py_DECREF(item);
            break;
        case TG_STEP_BAD_CHECKSUM:
            if (rare_event(parser, buf, out, TG_R_BAD_CHECKSUM, &st, NULL) < 0) return -1;
            break;
        default: /* DISCARD: line ends between frames are no news */
            if ((st.reason == TG_R_OVERSIZE || !only_separators(p + st.start, st.end - st.start)) &&
                rare_event(parser, buf, out, st.reason, &st, NULL) < 0)
                return -1;
        }
        pos = (Py_ssize_t)st.next;
    }
}

static int add_to_stat(PyObject *stats, PyObject *name, Py_ssize_t n) {
    PyObject *v, *sum, *inc;
    int r;
    if (!n) return 0;
    v = PyObject_GetAttr(stats, name);
    if (!v) return -1;
    inc = PyLong_FromSsize_t(n);
    sum = inc ? PyNumber_Add(v, inc) : NULL;
    Py_DECREF(v);
    Py_XDECREF(inc);
    if (!sum) return -1;
    r = PyObject_SetAttr(stats, name, sum);
    Py_DECREF(sum);
    return r;
}

/* Decode every frame of out in place (after the scan, as the pure path does). */
static int decode_items(PyObject *out, PyObject *decode, PyTypeObject *frame_cls) {
    Py_ssize_t k, n = PyList_GET_SIZE(out);
    for (k = 0; k < n; k++) {
        PyObject *item = PyList_GET_ITEM(out, k), *m;
        if (Py_TYPE(item) != frame_cls) continue;
        if (Py_IS_TYPE(decode, &DecoderType))
            m = decoder_decode((Decoder *)decode, item);
        else if (Py_IS_TYPE(decode, &AnyDecoderType))
            m = any_decode((AnyDecoder *)decode, item);
        else
            m = PyObject_CallOneArg(decode, item);
        if (!m) return -1;
        PyList_SET_ITEM(out, k, m); /* steals m */
        Py_DECREF(item);
    }
    return 0;
}

/* FrameParser._feed_py in C: the same events, statistics and buffer. */
static PyObject *feed(PyObject *parser, PyObject *data, int final, PyObject *decode, PyTypeObject *frame_cls) {
    PyObject *old = NULL, *buf = NULL, *out = NULL, *v, *rest, *stats;
    Py_ssize_t dlen, pos, nframes = 0, maxd;
    tg_scan_cfg cfg;
    int recover;
    if (PyBytes_CheckExact(data)) {
        Py_INCREF(data);
        dlen = PyBytes_GET_SIZE(data);
    } else {
        /* len(data) then bytes(data), as the pure path: an int is a TypeError there (bytes(n)
         * would make n zero bytes), and the statistics count what len() says */
        if ((dlen = PyObject_Size(data)) < 0) return NULL;
        if (!(data = PyObject_CallOneArg((PyObject *)&PyBytes_Type, data))) return NULL;
    }
    old = PyObject_GetAttr(parser, s_buf);
    if (!old) goto error;
    if (!PyBytes_Check(old)) {
        PyErr_SetString(PyExc_TypeError, "FrameParser._buf must be bytes");
        goto error;
    }
    if (PyBytes_GET_SIZE(old) == 0) {
        buf = data;
        Py_INCREF(buf);
    } else {
        buf = old;
        Py_INCREF(buf);
        PyBytes_Concat(&buf, data); /* a new object: `old` keeps its own reference */
        if (!buf) goto error;
    }
    v = PyObject_GetAttr(parser, s_max_data);
    maxd = v ? PyLong_AsSsize_t(v) : -1;
    Py_XDECREF(v);
    if (maxd == -1 && PyErr_Occurred()) goto error;
    v = PyObject_GetAttr(parser, s_recover);
    recover = v ? PyObject_IsTrue(v) : -1;
    Py_XDECREF(v);
    if (recover < 0) goto error;
    cfg.max_data = maxd < 0 ? 0 : (maxd > 0xFFFF ? 0xFFFF : (uint32_t)maxd);
    cfg.recover_length = (uint8_t)recover;
    stats = PyObject_GetAttr(parser, s_stats);
    if (!stats) goto error;
    if (add_to_stat(stats, s_bytes, dlen) < 0) {
        Py_DECREF(stats);
        goto error;
    }
    out = PyList_New(0);
    if (!out) {
        Py_DECREF(stats);
        goto error;
    }
    pos = scan_into(parser, buf, 0, 0, &cfg, frame_cls, out, &nframes);
    if (pos >= 0 && final) { /* the rest as if the stream ended here */
        pos = scan_into(parser, buf, pos, 1, &cfg, frame_cls, out, &nframes);
        if (pos >= 0 && pos < PyBytes_GET_SIZE(buf)) {
            tg_step st;
            memset(&st, 0, sizeof st);
            st.start = (size_t)pos;
            st.end = st.next = (size_t)PyBytes_GET_SIZE(buf);
            if (!only_separators((const uint8_t *)PyBytes_AS_STRING(buf) + pos, st.end - st.start) &&
                rare_event(parser, buf, out, TG_R_END_OF_STREAM, &st, NULL) < 0)
                pos = -1;
            else
                pos = PyBytes_GET_SIZE(buf);
        }
    }
    if (pos < 0 || add_to_stat(stats, s_frames, nframes) < 0) {
        Py_DECREF(stats);
        goto error;
    }
    Py_DECREF(stats);
    rest = pos == 0 ? (Py_INCREF(buf), buf)
                    : PyBytes_FromStringAndSize(PyBytes_AS_STRING(buf) + pos, PyBytes_GET_SIZE(buf) - pos);
    if (!rest || PyObject_SetAttr(parser, s_buf, rest) < 0) {
        Py_XDECREF(rest);
        goto error;
    }
    Py_DECREF(rest);
    Py_DECREF(old);
    Py_DECREF(buf);
    Py_DECREF(data);
    if (decode && decode != Py_None && decode_items(out, decode, frame_cls) < 0) {
        Py_DECREF(out);
        return NULL;
    }
    return out;
error:
    Py_XDECREF(out);
    Py_XDECREF(old);
    Py_XDECREF(buf);
    Py_DECREF(data);
    return NULL;
}

/* FrameParser's feed / feed_datagram / flush / feed_messages as C methods (a method descriptor:
 * `parser.feed(data)` calls straight into C with the parser as first argument). */
enum { M_FEED = 0, M_DATAGRAM, M_FLUSH, M_MESSAGES };

typedef struct {
    PyObject_HEAD
    vectorcallfunc vectorcall;
    int kind;
    PyTypeObject *frame_cls;
    PyObject *wrapped; /* the pure method it stands for (docs, signature) */
} ParserMethod;

static PyTypeObject ParserMethodType;

static PyObject *ParserMethod_vectorcall(PyObject *callable, PyObject *const *args, size_t nargsf, PyObject *kwnames) {
    ParserMethod *m = (ParserMethod *)callable;
    Py_ssize_t nargs = PyVectorcall_NARGS(nargsf), nkw = kwnames ? PyTuple_GET_SIZE(kwnames) : 0;
    static const Py_ssize_t want[4] = {2, 2, 1, 3};
    int final = m->kind == M_DATAGRAM || m->kind == M_FLUSH;
    if (m->kind == M_MESSAGES) {
        if (nkw > 1 || (nkw == 1 && PyUnicode_Compare(PyTuple_GET_ITEM(kwnames, 0), s_final) != 0) ||
            nargs != 3) {
            if (!PyErr_Occurred())
                PyErr_SetString(PyExc_TypeError, "feed_messages(data, decode, *, final=False)");
            return NULL;
        }
        if (nkw == 1 && (final = PyObject_IsTrue(args[nargs])) < 0) return NULL;
        return feed(args[0], args[1], final, args[2], m->frame_cls);
    }
    if (nargs != want[m->kind] || nkw) {
        PyErr_SetString(PyExc_TypeError, m->kind == M_FLUSH ? "flush() takes no arguments" : "takes one argument: data");
        return NULL;
    }
    if (m->kind == M_FLUSH) {
        PyObject *empty = PyBytes_FromStringAndSize("", 0), *r;
        if (!empty) return NULL;
        r = feed(args[0], empty, 1, NULL, m->frame_cls);
        Py_DECREF(empty);
        return r;
    }
    return feed(args[0], args[1], final, NULL, m->frame_cls);
}

static PyObject *ParserMethod_get(PyObject *self, PyObject *obj, PyObject *type) {
    (void)type;
    if (obj == NULL || obj == Py_None) {
        Py_INCREF(self);
        return self;
    }
    return PyMethod_New(self, obj);
}

static PyObject *ParserMethod_new(PyTypeObject *type, PyObject *args, PyObject *kw) {
    int kind;
    PyObject *frame_cls, *wrapped;
    ParserMethod *self;
    (void)kw;
    if (!PyArg_ParseTuple(args, "iO!O", &kind, &PyType_Type, &frame_cls, &wrapped)) return NULL;
    if (kind < M_FEED || kind > M_MESSAGES || !PyType_IsSubtype((PyTypeObject *)frame_cls, &PyTuple_Type))
        return PyErr_Format(PyExc_ValueError, "ParserMethod(kind 0..3, a tuple subclass, the pure method)");
    self = (ParserMethod *)type->tp_alloc(type, 0);
    if (!self) return NULL;
    self->vectorcall = ParserMethod_vectorcall;
    self->kind = kind;
    Py_INCREF(frame_cls);
    self->frame_cls = (PyTypeObject *)frame_cls;
    Py_INCREF(wrapped);
    self->wrapped = wrapped;
    return (PyObject *)self;
}

static void ParserMethod_dealloc(ParserMethod *self) {
    Py_XDECREF(self->frame_cls);
    Py_XDECREF(self->wrapped);
    Py_TYPE(self)->tp_free((PyObject *)self);
}

static PyObject *ParserMethod_getattro(PyObject *self, PyObject *name) {
    /* __doc__, __name__, __wrapped__ ... of the pure method it stands for */
    PyObject *r = PyObject_GenericGetAttr(self, name);
    if (r || !PyErr_ExceptionMatches(PyExc_AttributeError)) return r;
    PyErr_Clear();
    return PyObject_GetAttr(((ParserMethod *)self)->wrapped, name);
}

static PyObject *ParserMethod_wrapped(ParserMethod *self, void *closure) {
    (void)closure;
    Py_INCREF(self->wrapped);
    return self->wrapped;
}

static PyObject *ParserMethod_doc(ParserMethod *self, void *closure) {
    (void)closure;
    return PyObject_GetAttrString(self->wrapped, "__doc__");
}

static PyGetSetDef ParserMethod_getset[] = {
    {"__wrapped__", (getter)ParserMethod_wrapped, NULL, "the pure Python method", NULL},
    {"__doc__", (getter)ParserMethod_doc, NULL, NULL, NULL},
    {NULL, NULL, NULL, NULL, NULL}};

/* ---- module ------------------------------------------------------------------------------- */

/* Every type here is a vectorcall object with its own dealloc: the head they share. */
#define VECTORCALL_TYPE(NAME, STRUCT, DEALLOC, FLAGS)                                   \
    PyVarObject_HEAD_INIT(NULL, 0).tp_name = "topgimbal._speedups._ctop." NAME,        \
    .tp_basicsize = sizeof(STRUCT), .tp_dealloc = (destructor)(DEALLOC),                \
    .tp_vectorcall_offset = offsetof(STRUCT, vectorcall), .tp_call = PyVectorcall_Call, \
    .tp_flags = Py_TPFLAGS_DEFAULT | Py_TPFLAGS_HAVE_VECTORCALL | (FLAGS)

static PyTypeObject DecoderType = {
    VECTORCALL_TYPE("Decoder", Decoder, Decoder_dealloc, 0),
    .tp_doc = "Decoder(commands, message_cls, fallback, name, headers, host_addresses): Dialect.decode in C.",
    .tp_methods = Decoder_methods,
    .tp_getset = Decoder_getset,
    .tp_init = (initproc)Decoder_init,
    .tp_new = Decoder_new,
};

static PyTypeObject AnyDecoderType = {
    VECTORCALL_TYPE("AnyDecoder", AnyDecoder, AnyDecoder_dealloc, 0),
    .tp_doc = "AnyDecoder(prefer, candidates, fallback): decode_any in C.",
    .tp_new = AnyDecoder_new,
};

static PyTypeObject ParserMethodType = {
    VECTORCALL_TYPE("ParserMethod", ParserMethod, ParserMethod_dealloc, Py_TPFLAGS_METHOD_DESCRIPTOR),
    .tp_getattro = ParserMethod_getattro,
    .tp_descr_get = ParserMethod_get,
    .tp_doc = "ParserMethod(kind, frame_cls, pure): a FrameParser method in C.",
    .tp_getset = ParserMethod_getset,
    .tp_new = ParserMethod_new,
};

#undef VECTORCALL_TYPE

/* The module's types by the name it exports them under: readied and added in one loop. */
static struct {
    const char *name;
    PyTypeObject *type;
} module_types[] = {{"Decoder", &DecoderType}, {"AnyDecoder", &AnyDecoderType}, {"ParserMethod", &ParserMethodType}};

/* ---- many datagrams in one system call ---------------------------------------------------- */

#if defined(__linux__)
#include <arpa/inet.h>
#include <errno.h>
#include <netinet/in.h>
#include <sys/socket.h>

#define RECV_MANY_MAX 64
#define RECV_MANY_SLOT 65536 /* a whole UDP datagram, as the pure loop's buffer: nothing truncated */

/* One buffer for the process, used under the GIL (the call never releases it: MSG_DONTWAIT never
 * waits). Only the bytes the datagrams fill are ever touched. */
static char *recv_slots;

static PyObject *ipv4_address(const struct sockaddr_in *sin) {
    char host[INET_ADDRSTRLEN];
    PyObject *h, *port, *out;
    if (!inet_ntop(AF_INET, &sin->sin_addr, host, sizeof host)) return PyErr_SetFromErrno(PyExc_OSError);
    if (!(h = PyUnicode_FromString(host))) return NULL;
    if (!(port = PyLong_FromLong(ntohs(sin->sin_port)))) {
        Py_DECREF(h);
        return NULL;
    }
    out = PyTuple_Pack(2, h, port);
    Py_DECREF(h);
    Py_DECREF(port);
    return out;
}

static PyObject *recv_many(PyObject *mod, PyObject *args) {
    int fd, max, n, k;
    struct mmsghdr msgs[RECV_MANY_MAX];
    struct iovec iov[RECV_MANY_MAX];
    struct sockaddr_storage addrs[RECV_MANY_MAX];
    PyObject *out;
    (void)mod;
    if (!PyArg_ParseTuple(args, "ii:recv_many", &fd, &max)) return NULL;
    if (fd < 0) {
        PyErr_Format(PyExc_ValueError, "recv_many: file descriptor %d: expected an open socket's (>= 0)", fd);
        return NULL;
    }
    if (max < 1 || max > RECV_MANY_MAX) {
        PyErr_Format(PyExc_ValueError, "recv_many: max %d: expected 1..%d datagrams", max, RECV_MANY_MAX);
        return NULL;
    }
    if (!recv_slots && !(recv_slots = PyMem_RawMalloc((size_t)RECV_MANY_MAX * RECV_MANY_SLOT))) return PyErr_NoMemory();
    memset(msgs, 0, sizeof msgs);
    for (k = 0; k < max; k++) {
        iov[k].iov_base = recv_slots + (size_t)k * RECV_MANY_SLOT;
        iov[k].iov_len = RECV_MANY_SLOT;
        msgs[k].msg_hdr.msg_iov = &iov[k];
        msgs[k].msg_hdr.msg_iovlen = 1;
        msgs[k].msg_hdr.msg_name = &addrs[k];
        msgs[k].msg_hdr.msg_namelen = sizeof addrs[k];
    }
    n = recvmmsg(fd, msgs, (unsigned int)max, MSG_DONTWAIT, NULL);
    if (n < 0) {
        if (errno == EAGAIN || errno == EWOULDBLOCK || errno == EINTR) return PyList_New(0);
        return PyErr_SetFromErrno(PyExc_OSError);
    }
    if (!(out = PyList_New(n))) return NULL;
    for (k = 0; k < n; k++) {
        PyObject *data, *addr, *item;
        if (!(data = PyBytes_FromStringAndSize(iov[k].iov_base, (Py_ssize_t)msgs[k].msg_len))) goto fail;
        if (msgs[k].msg_hdr.msg_namelen >= sizeof(struct sockaddr_in) && addrs[k].ss_family == AF_INET) {
            addr = ipv4_address((const struct sockaddr_in *)&addrs[k]);
        } else { /* not IPv4: no route has such an address (the caller counts a stranger) */
            addr = Py_None;
            Py_INCREF(addr);
        }
        if (!addr) {
            Py_DECREF(data);
            goto fail;
        }
        item = PyTuple_Pack(2, data, addr);
        Py_DECREF(data);
        Py_DECREF(addr);
        if (!item) goto fail;
        PyList_SET_ITEM(out, k, item);
    }
    return out;
fail:
    Py_DECREF(out);
    return NULL;
}
#endif

static PyMethodDef module_functions[] = {
#if defined(__linux__)
    {"recv_many", recv_many, METH_VARARGS,
     "recv_many(fd, max) -> [(data, (host, port) | None), ...]: up to `max` (1..64) datagrams of a non-blocking "
     "IPv4 UDP socket in one recvmmsg call; [] when none is waiting. The address is None for any other family."},
#endif
    {NULL, NULL, 0, NULL}};

static struct PyModuleDef module = {PyModuleDef_HEAD_INIT, "_ctop", "libtopgimbal fast path", -1, module_functions,
                                    NULL, NULL, NULL, NULL};

PyMODINIT_FUNC PyInit__ctop(void) {
    PyObject *m;
    static const char *const texts[5] = {"", "#TP", "#tp", "#tP", "#Tp"};
    size_t k;
    for (k = 0; k < sizeof module_types / sizeof module_types[0]; k++)
        if (PyType_Ready(module_types[k].type) < 0) return NULL;
    for (k = 0; k < 5; k++)
        if (!headers[k] && !(headers[k] = PyUnicode_InternFromString(texts[k]))) return NULL;
#define INTERN(var, text) \
    if (!var && !(var = PyUnicode_InternFromString(text))) return NULL
    INTERN(s_buf, "_buf");
    INTERN(s_stats, "stats");
    INTERN(s_bytes, "bytes");
    INTERN(s_frames, "frames");
    INTERN(s_max_data, "max_data_length");
    INTERN(s_recover, "recover_length");
    INTERN(s_c_event, "_c_event");
    INTERN(s_final, "final");
    INTERN(s_decode, "decode");
#undef INTERN
    m = PyModule_Create(&module);
    if (!m) return NULL;
    for (k = 0; k < sizeof module_types / sizeof module_types[0]; k++) {
        Py_INCREF(module_types[k].type);
        if (PyModule_AddObject(m, module_types[k].name, (PyObject *)module_types[k].type) < 0) {
            Py_DECREF(module_types[k].type);
            Py_DECREF(m);
            return NULL;
        }
    }
    if (PyModule_AddIntConstant(m, "ABI_VERSION", ABI_VERSION) < 0) {
        Py_DECREF(m);
        return NULL;
    }
    return m;
}
