/*
 * asan_box.c: a small iSight AI Box in C with one planted heap overflow (the fuzzer's last-words tests).
 *
 * It frames the stream as PROTOCOL.md says (a header whose start word and version are right is trusted;
 * otherwise it resynchronises at the next FE FE; more than the largest legal frame closes the connection),
 * answers NONE, CycleOn, CycleOff, poses, register poses and tolerances, answers a malformed request with
 * A3's error and stays silent to what is not a request (A5). One thread per connection.
 *
 * The planted defect: the tolerance table has room for 6 blocks and its bound is off by one, so a
 * tolerance request of exactly 7 blocks writes 5 bytes past the end of a 30-byte heap buffer. Built
 * plainly, those bytes land in malloc's slack and nothing shows on the wire; built with
 * -fsanitize=address the write is a heap-buffer-overflow, AddressSanitizer reports it on stderr and the
 * process exits: the box dies.
 *
 *   gcc -O1 -g -pthread tests/impls/asan_box.c -o asan_box                      (plain)
 *   gcc -O1 -g -fsanitize=address,undefined -fno-omit-frame-pointer -pthread \
 *       tests/impls/asan_box.c -o asan_box                                       (sanitized)
 *   ./asan_box 9100        (prints "listening 9100")
 */
#include <arpa/inet.h>
#include <netinet/in.h>
#include <netinet/tcp.h>
#include <pthread.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/socket.h>
#include <unistd.h>

#define HEADER 12
#define CHECK 2
#define MAX_FRAME (HEADER + 255 * 25 + CHECK)
#define TOLERANCE_ROOM 6
#define TOLERANCE_BLOCK 5

static void answer(int fd, unsigned action, unsigned code) {
    unsigned char a[HEADER + CHECK] = {0xFE, 0xFE, 0x00, 0x01, 0x10, (unsigned char)action, 0, 0, 0, 0,
                                       (unsigned char)(code >> 8), (unsigned char)(code & 0xFF), 0, 0};
    send(fd, a, sizeof a, MSG_NOSIGNAL);
}

static int finite_be(const unsigned char *p) {
    uint32_t u = (uint32_t)p[0] << 24 | (uint32_t)p[1] << 16 | (uint32_t)p[2] << 8 | p[3];
    return (u & 0x7F800000u) != 0x7F800000u;
}

/* The tolerances in force (the last request's), shared by every connection. */
static unsigned char *tolerances;
static unsigned tolerance_count;
static pthread_mutex_t tolerance_lock = PTHREAD_MUTEX_INITIALIZER;

/* The planted defect: room for TOLERANCE_ROOM blocks, a bound of TOLERANCE_ROOM + 1. */
static void store_tolerances(const unsigned char *body, unsigned n) {
    unsigned keep = n <= TOLERANCE_ROOM + 1 ? n : TOLERANCE_ROOM; /* BUG: should be n <= TOLERANCE_ROOM */
    unsigned char *table = malloc(TOLERANCE_ROOM * TOLERANCE_BLOCK);
    if (table == NULL)
        return;
    memcpy(table, body, (size_t)keep * TOLERANCE_BLOCK);
    pthread_mutex_lock(&tolerance_lock);
    free(tolerances);
    tolerances = table;
    tolerance_count = keep;
    pthread_mutex_unlock(&tolerance_lock);
}

static void handle(int fd, const unsigned char *f, unsigned n, unsigned len) {
    unsigned action = f[5], bt = f[6];
    const unsigned char *body = f + HEADER;
    if (f[4] != 0x01)
        return; /* not a robot-to-box frame: not a request (A5) */
    if (action <= 2) {
        if (bt == 0 && n == 0 && len == 0)
            answer(fd, action, 0);
        else if (action != 0)
            answer(fd, action, action == 1 ? 0x0001 : 0x0002);
        return;
    }
    if (action < 0x23 || action > 0x25)
        return; /* unknown action: not a request (A5) */
    unsigned want_bt = action == 0x25 ? 2 : 1, want_len = action == 0x25 ? 5 : 25;
    unsigned error = action == 0x25 ? 0x1002 : 0x1001;
    if (bt != want_bt || len != want_len || n < 1) {
        answer(fd, action, error);
        return;
    }
    for (unsigned i = 0; i < n; i++) {
        const unsigned char *block = body + (size_t)i * len;
        if (block[0] != (i & 0xFF)) {
            answer(fd, action, error);
            return;
        }
        for (unsigned at = 1; at < len; at += 4)
            if (!finite_be(block + at)) {
                answer(fd, action, error);
                return;
            }
    }
    if (action == 0x25)
        store_tolerances(body, n);
    answer(fd, action, 0);
}

static void *serve(void *arg) {
    int fd = (int)(intptr_t)arg;
    static __thread unsigned char buf[2 * MAX_FRAME];
    size_t have = 0;
    for (;;) {
        ssize_t got = recv(fd, buf + have, sizeof buf - have, 0);
        if (got <= 0)
            break;
        have += (size_t)got;
        for (;;) {
            size_t skip = 0;
            while (skip + 1 < have && !(buf[skip] == 0xFE && buf[skip + 1] == 0xFE))
                skip++;
            if (have == 1 && buf[0] != 0xFE)
                skip = 1;
            memmove(buf, buf + skip, have - skip);
            have -= skip;
            if (have < HEADER)
                break;
            if (buf[2] != 0x00 || buf[3] != 0x01) { /* not a frame: resynchronise past this FE */
                memmove(buf, buf + 1, have - 1);
                have--;
                continue;
            }
            unsigned n = buf[7], len = (unsigned)buf[8] << 8 | buf[9];
            size_t total = HEADER + (size_t)n * len + CHECK;
            if (total > MAX_FRAME)
                goto done; /* R5: more than the largest legal frame: close */
            if (have < total)
                break;
            handle(fd, buf, n, len);
            memmove(buf, buf + total, have - total);
            have -= total;
        }
    }
done:
    close(fd);
    return NULL;
}

int main(int argc, char **argv) {
    int port = argc > 1 ? atoi(argv[1]) : 0;
    int srv = socket(AF_INET, SOCK_STREAM, 0), one = 1;
    struct sockaddr_in addr = {0};
    socklen_t size = sizeof addr;
    setsockopt(srv, SOL_SOCKET, SO_REUSEADDR, &one, sizeof one);
    addr.sin_family = AF_INET;
    addr.sin_port = htons((uint16_t)port);
    addr.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    if (bind(srv, (struct sockaddr *)&addr, sizeof addr) || listen(srv, 64)) {
        perror("asan_box: bind");
        return 2;
    }
    getsockname(srv, (struct sockaddr *)&addr, &size);
    printf("listening %d\n", ntohs(addr.sin_port));
    fflush(stdout);
    for (;;) {
        int fd = accept(srv, NULL, NULL);
        pthread_t thread;
        if (fd < 0)
            continue;
        setsockopt(fd, IPPROTO_TCP, TCP_NODELAY, &one, sizeof one);
        if (pthread_create(&thread, NULL, serve, (void *)(intptr_t)fd) == 0)
            pthread_detach(thread);
        else
            close(fd);
    }
}
