/* How much slower memory reads after the host let the CPU idle: the cause
 * of hannes-run's slowdown at the camera's pace (BENCHMARKS.md, issue 59).
 *
 * Each of 300 rounds sleeps SLEEP_US (0: back to back), then reads a
 * KIB-KiB buffer twice, one float per cache line; prints the median of
 * each read in microseconds. HUGE=1 maps the buffer on 2 MiB pages
 * (madvise MADV_HUGEPAGE).
 *
 *   gcc -O2 -o /tmp/idle_probe lab/idle_memory_probe.c
 *   /tmp/idle_probe 0 16384 0; /tmp/idle_probe 26000 16384 0; /tmp/idle_probe 26000 16384 1
 */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/mman.h>
#include <time.h>

static double now_us(void) {
    struct timespec t;
    clock_gettime(CLOCK_MONOTONIC, &t);
    return t.tv_sec * 1e6 + t.tv_nsec * 1e-3;
}

static int by_value(const void *a, const void *b) {
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

static volatile float sink;

static double read_all(const float *a, size_t n) {
    double t = now_us();
    float s = 0;
    for (size_t i = 0; i < n; i += 16) s += a[i];
    sink = s;
    return now_us() - t;
}

int main(int argc, char **argv) {
    if (argc != 4) {
        fprintf(stderr, "usage: %s SLEEP_US KIB HUGE(0|1)\n", argv[0]);
        return 2;
    }
    long sleep_us = atol(argv[1]);
    size_t bytes = (size_t)atol(argv[2]) * 1024, align = 2u << 20;
    size_t size = (bytes + align - 1) / align * align;
    float *a = aligned_alloc(align, size);
    if (!a) return 1;
    if (atoi(argv[3])) madvise(a, size, MADV_HUGEPAGE);
    memset(a, 0, size);
    enum { ROUNDS = 300 };
    double first[ROUNDS], second[ROUNDS];
    for (int r = 0; r < ROUNDS; r++) {
        if (sleep_us) {
            struct timespec q = {sleep_us / 1000000, (sleep_us % 1000000) * 1000};
            nanosleep(&q, NULL);
        }
        first[r] = read_all(a, bytes / 4);
        second[r] = read_all(a, bytes / 4);
    }
    qsort(first, ROUNDS, sizeof(double), by_value);
    qsort(second, ROUNDS, sizeof(double), by_value);
    printf("sleep %ld us, %zu KiB, huge %s: first read %.0f us, second %.0f us (medians)\n",
           sleep_us, bytes / 1024, argv[3], first[ROUNDS / 2], second[ROUNDS / 2]);
    return 0;
}
