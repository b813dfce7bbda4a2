/* The control of the encoder packages' timing: a busy loop of `work` dependent
   multiply-adds, timed exactly as `timing.c` times a sample (clock_gettime around each of
   `samples` calls). Its tail is what the machine does to any window of that length: the
   packages' tail beyond it would be their own. Usage: timing_control work samples; prints
   one JSON object (median_us, p999_us, p9999_us, max_us, over_10x_median). */
#define _POSIX_C_SOURCE 199309L
#include <stdio.h>
#include <stdlib.h>
#include <time.h>

#define MAX_SAMPLES 10000000L

static double spent[MAX_SAMPLES];

static int by_value(const void *a, const void *b) {
  double x = *(const double *)a, y = *(const double *)b;
  return (x > y) - (x < y);
}

static double now(void) {
  struct timespec t;
  clock_gettime(CLOCK_MONOTONIC, &t);
  return (double)t.tv_sec + 1e-9 * (double)t.tv_nsec;
}

int main(int argc, char **argv) {
  long work, samples, i, k, slow = 0;
  volatile double sink = 1.0;
  if (argc != 3) return 2;
  work = strtol(argv[1], NULL, 10);
  samples = strtol(argv[2], NULL, 10);
  if (work < 0 || samples < 1 || samples > MAX_SAMPLES) return 2;
  for (i = 0; i < samples; ++i) {
    double start = now(), value = sink;
    for (k = 0; k < work; ++k) value = value * 1.0000001 + 1e-9;
    sink = value;
    spent[i] = now() - start;
  }
  qsort(spent, (size_t)samples, sizeof spent[0], by_value);
  for (i = 0; i < samples; ++i) slow += spent[i] > 10.0 * spent[samples / 2];
  printf("{\"median_us\": %.3f, \"p999_us\": %.3f, \"p9999_us\": %.3f, \"max_us\": %.3f, "
         "\"over_10x_median\": %ld}\n", 1e6 * spent[samples / 2],
         1e6 * spent[(long)(0.999 * (double)(samples - 1))],
         1e6 * spent[(long)(0.9999 * (double)(samples - 1))], 1e6 * spent[samples - 1], slow);
  return 0;
}
