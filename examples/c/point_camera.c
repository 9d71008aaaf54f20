/*
 * Point a SkyDroid camera (C10..C20) with libtopgimbal, over UDP or a POSIX serial port:
 *
 *     point_camera udp 127.0.0.1 5000 YAW PITCH          (a camera, or `topgimbal sim --model C12`)
 *     point_camera serial /dev/ttyUSB0 115200 YAW PITCH
 *
 * Sends GAM (yaw and pitch angles, degrees as on the wire) and waits up to 1 s for its echo, then
 * asks GAC (attitude) ten times a second until both axes are within 0.5 degrees, and prints the
 * attitude. Exit 0 when reached, 1 on timeout (15 s), 2 on a usage or I/O error (a message on
 * stderr says which argument or call failed and what is allowed), 3 when the camera refuses with
 * its error frame (ERE): at once, e.g. pitch -60 on a C12, whose pitch range is -45..45 (the GAM
 * field here allows -90..90: the model's own range is the camera's to enforce). An ERE names no
 * command: it is the GAM's while only the GAM waits for an answer, the GAC's after that. Firmware
 * that does not echo motion commands (C13) is polled after the 1 s.
 *
 * What the library needs from this host program is what an RTOS port supplies (docs/c.md): a way
 * to send bytes (send_bytes), bytes received (fed to the parser) and a clock (now_ms).
 */
#define _DEFAULT_SOURCE /* cfmakeraw */
#include <arpa/inet.h>
#include <errno.h>
#include <math.h>
#include <fcntl.h>
#include <poll.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/socket.h>
#include <termios.h>
#include <time.h>
#include <unistd.h>

#include "tg_catalog.h"

static int fd = -1;
static struct sockaddr_in peer;
static int is_udp;

static long now_ms(void) {
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return ts.tv_sec * 1000L + ts.tv_nsec / 1000000L;
}

static int send_bytes(const uint8_t *p, size_t n) {
    ssize_t w = is_udp ? sendto(fd, p, n, 0, (const struct sockaddr *)&peer, sizeof peer) : write(fd, p, n);
    return w == (ssize_t)n ? 0 : -1;
}

/* A whole decimal number in [lo, hi], or -1 with a message naming the argument. */
static long whole_number(const char *what, const char *text, long lo, long hi) {
    char *end;
    long v;
    errno = 0;
    v = strtol(text, &end, 10);
    if (end == text || *end || errno || v < lo || v > hi) {
        fprintf(stderr, "bad %s '%s': expected a whole number %ld..%ld\n", what, text, lo, hi);
        return -1;
    }
    return v;
}

static int open_udp(const char *host, const char *port) {
    struct sockaddr_in local;
    long p = whole_number("port", port, 1, 65535);
    if (p < 0) return -1;
    memset(&peer, 0, sizeof peer);
    peer.sin_family = AF_INET;
    peer.sin_port = htons((uint16_t)p);
    if (inet_pton(AF_INET, host, &peer.sin_addr) != 1) {
        fprintf(stderr, "bad host '%s': expected a dotted IPv4 address such as 127.0.0.1\n", host);
        return -1;
    }
    fd = socket(AF_INET, SOCK_DGRAM, 0);
    memset(&local, 0, sizeof local);
    local.sin_family = AF_INET; /* any port: the camera answers whoever asked */
    is_udp = 1;
    if (fd < 0 || bind(fd, (const struct sockaddr *)&local, sizeof local) != 0) {
        fprintf(stderr, "cannot open a UDP socket: %s\n", strerror(errno));
        return -1;
    }
    return 0;
}

static int open_serial(const char *dev, const char *baud) {
    struct termios t;
    long b = whole_number("baud rate", baud, 1, 4000000);
    speed_t speed = b == 115200 ? B115200 : (b == 57600 ? B57600 : B9600);
    if (b < 0) return -1;
    if (b != 9600 && b != 57600 && b != 115200) {
        fprintf(stderr, "bad baud rate '%s': expected 9600, 57600 or 115200\n", baud);
        return -1;
    }
    fd = open(dev, O_RDWR | O_NOCTTY);
    if (fd < 0 || tcgetattr(fd, &t) != 0) {
        fprintf(stderr, "cannot open serial device %s: %s\n", dev, strerror(errno));
        return -1;
    }
    cfmakeraw(&t);
    cfsetispeed(&t, speed);
    cfsetospeed(&t, speed);
    if (tcsetattr(fd, TCSANOW, &t) != 0) {
        fprintf(stderr, "cannot set up serial device %s: %s\n", dev, strerror(errno));
        return -1;
    }
    return 0;
}

/* Encode a request of the SkyDroid dialect and send it. */
static int request(unsigned cmd, unsigned form, const tg_value *values) {
    uint8_t frame[TG_FRAME_MAX];
    const tg_command *c = &tg_skydroid.commands[cmd];
    int n = tg_encode(&tg_skydroid, c, &c->forms[form], 'U', c->address, 0, values, frame, sizeof frame);
    if (n < 0) {
        fprintf(stderr, "cannot encode %.3s: %s\n", c->ident, tg_status_text(n));
        return -1;
    }
    if (send_bytes(frame, (size_t)n) != 0) {
        fprintf(stderr, "cannot send %.3s: %s\n", c->ident, strerror(errno));
        return -1;
    }
    return 0;
}

/* An angle argument in hundredths of a degree, checked against the GAM field it goes to (a
 * double outside int64_t would make the conversion undefined: the range is checked first). */
static int degrees(const char *what, const char *text, unsigned field, tg_value *out) {
    const tg_codec *c = tg_skydroid.commands[TG_SKYDROID_GAM].forms[TG_SKYDROID_GAM_W_REQ].fields[field].codec;
    int64_t lo, hi;
    tg_value bound = tg_num(c->lo, c->exp10);
    char *end;
    double v;
    errno = 0;
    v = strtod(text, &end);
    tg_value_rescale(&bound, -2, &lo);
    bound.num = c->hi;
    tg_value_rescale(&bound, -2, &hi);
    if (end == text || *end || errno || !isfinite(v) || v * 100.0 < (double)lo - 0.5 || v * 100.0 > (double)hi + 0.5) {
        fprintf(stderr, "bad %s '%s': expected degrees %.2f..%.2f\n", what, text, (double)lo / 100, (double)hi / 100);
        return -1;
    }
    *out = tg_num((int64_t)(v * 100.0 + (v < 0 ? -0.5 : 0.5)), -2); /* hundredths of a degree */
    return 0;
}

/* What a received frame is to this program. */
enum { OTHER, REFUSED, GAM_ECHO, ATTITUDE };

static int classify(const tg_frame *frame, tg_message *m) {
    if (tg_decode(&tg_skydroid, frame, m) != TG_OK) return OTHER;
    if (m->cmd == &tg_skydroid.commands[TG_SKYDROID_ERE]) return REFUSED;
    if (m->form->direction != TG_RESPONSE) return OTHER;
    if (m->cmd == &tg_skydroid.commands[TG_SKYDROID_GAM]) return GAM_ECHO;
    if (m->cmd == &tg_skydroid.commands[TG_SKYDROID_GAC]) return ATTITUDE;
    return OTHER;
}

int main(int argc, char **argv) {
    static tg_parser parser;
    tg_value gam[4], none[1];
    int64_t want_yaw, want_pitch;
    long deadline, next_query = 0, echo_deadline;
    int opened, polling = 0;
    if (argc != 6 || (strcmp(argv[1], "udp") != 0 && strcmp(argv[1], "serial") != 0)) {
        fprintf(stderr, "usage: %s udp HOST PORT YAW PITCH | serial DEVICE BAUD YAW PITCH\n",
                argc > 0 ? argv[0] : "point_camera");
        return 2;
    }
    memset(gam, 0, sizeof gam); /* TG_V_ABSENT: the speeds take the catalog's defaults */
    if (degrees("yaw", argv[4], TG_SKYDROID_GAM_W_REQ_YAW_DEG, &gam[TG_SKYDROID_GAM_W_REQ_YAW_DEG]) != 0 ||
        degrees("pitch", argv[5], TG_SKYDROID_GAM_W_REQ_PITCH_DEG, &gam[TG_SKYDROID_GAM_W_REQ_PITCH_DEG]) != 0)
        return 2;
    opened = strcmp(argv[1], "udp") == 0 ? open_udp(argv[2], argv[3]) : open_serial(argv[2], argv[3]);
    if (opened != 0) return 2;
    want_yaw = gam[TG_SKYDROID_GAM_W_REQ_YAW_DEG].num;
    want_pitch = gam[TG_SKYDROID_GAM_W_REQ_PITCH_DEG].num;
    memset(none, 0, sizeof none);
    tg_parser_init(&parser, NULL);
    if (request(TG_SKYDROID_GAM, TG_SKYDROID_GAM_W_REQ, gam) != 0) return 2;
    deadline = now_ms() + 15000;
    echo_deadline = now_ms() + 1000;
    while (now_ms() < deadline) {
        struct pollfd pfd = {0, POLLIN, 0};
        uint8_t buf[512];
        ssize_t n;
        tg_event ev;
        pfd.fd = fd;
        if (!polling && now_ms() >= echo_deadline) polling = 1; /* no echo (C13): poll anyway */
        if (polling && now_ms() >= next_query) {
            if (request(TG_SKYDROID_GAC, TG_SKYDROID_GAC_R_REQ, none) != 0) return 2;
            next_query = now_ms() + 100;
        }
        if (poll(&pfd, 1, 20) <= 0) continue;
        n = read(fd, buf, sizeof buf);
        if (n <= 0) {
            if (n < 0 && errno == EINTR) continue;
            fprintf(stderr, "cannot read from %s: %s\n", argv[2], n < 0 ? strerror(errno) : "end of input");
            return 2;
        }
        tg_parser_feed(&parser, buf, (size_t)n);
        if (is_udp) tg_parser_flush(&parser); /* a datagram ends its frames */
        while (tg_parser_next(&parser, &ev)) {
            tg_message m;
            int64_t yaw, pitch;
            int kind = ev.type == TG_EV_FRAME ? classify(&ev.frame, &m) : OTHER;
            if (kind == REFUSED) {
                if (polling)
                    fprintf(stderr, "the camera refused the attitude query (GAC) with its error frame (ERE)\n");
                else
                    fprintf(stderr, "the camera refused the angles (GAM yaw %.2f pitch %.2f) with its error frame "
                            "(ERE): outside this model's range?\n", (double)want_yaw / 100, (double)want_pitch / 100);
                return 3;
            }
            if (kind == GAM_ECHO) polling = 1; /* accepted: watch the attitude */
            if (kind != ATTITUDE) continue;
            if (tg_value_rescale(&m.values[TG_SKYDROID_GAC_R_RSP_YAW_DEG], -2, &yaw) != TG_OK ||
                tg_value_rescale(&m.values[TG_SKYDROID_GAC_R_RSP_PITCH_DEG], -2, &pitch) != TG_OK)
                continue; /* not a number (a "no value" token): nothing to compare */
            printf("attitude yaw %.2f pitch %.2f\n", (double)yaw / 100, (double)pitch / 100);
            if (llabs(yaw - want_yaw) <= 50 && llabs(pitch - want_pitch) <= 50) {
                printf("reached yaw %.2f pitch %.2f\n", (double)yaw / 100, (double)pitch / 100);
                return 0;
            }
        }
    }
    fprintf(stderr, "timeout: the camera did not reach the target\n");
    return 1;
}
