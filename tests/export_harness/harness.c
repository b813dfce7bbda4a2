/* Test harness of an exported C package (see tests/test_export.py).
 *
 * Build with -DCDPR_HEADER='"<prefix>.h"' -DCDPR_PREFIX=<prefix> -DCDPR_UPPER=<PREFIX>.
 * Input (file named by argv[1]): a count, then per state
 *   q[n] dq[n] q_goal[n] k[n] r_d[n] (memory[nmem] dt, if nmem > 0) use_case_gains
 * (use_case_gains = 1 passes NULL for k and r_d). Output (stdout), one line per state:
 *   ret tau[n] alpha beta j[nj] flags (memory_next[nmem] memory0[nmem], if nmem > 0)
 *   l[n] W[n*n] M[n*n] V P[n*nj] A[n*nj]
 * where memory0 = initial_memory(q, q_goal, k, r_d).
 * Every array is heap-allocated at its exact size and the work memory is left
 * uninitialised, so that valgrind sees any out-of-bounds or uninitialised access. */
#include <stdio.h>
#include <stdlib.h>

#include CDPR_HEADER

#define CAT_(a, b) a##b
#define CAT(a, b) CAT_(a, b)
#define FN(suffix) CAT(CDPR_PREFIX, suffix)
#define N CAT(CDPR_UPPER, _N)
#define NJ CAT(CDPR_UPPER, _NJ)
#define NMEM CAT(CDPR_UPPER, _NMEM)
typedef FN(_work) work_t;

static double *vector(int size) { return (double *) malloc((size_t) size * sizeof(double)); }

static void put(const double *values, int size) {
  int i;
  for (i = 0; i < size; ++i) printf(" %.17g", values[i]);
}

static int read_vector(FILE *in, double *values, int size) {
  int i;
  for (i = 0; i < size; ++i)
    if (fscanf(in, "%lf", &values[i]) != 1) return -1;
  return 0;
}

int main(int argc, char **argv) {
  FILE *in;
  long count, s;
  int use_case_gains, ret;
  double alpha, beta, V;
  int flags;
  work_t *work = (work_t *) malloc(sizeof(work_t));
  double *q = vector(N), *dq = vector(N), *q_goal = vector(N), *k = vector(N), *r_d = vector(N);
  double *tau = vector(N), *j = vector(NJ), *l = vector(N), *W = vector(N * N);
  double *M = vector(N * N), *P = vector(N * NJ), *A = vector(N * NJ);
#if NMEM > 0
  double *memory = vector(NMEM), *memory_next = vector(NMEM), *memory0 = vector(NMEM), dt;
#endif

  if (argc != 2 || (in = fopen(argv[1], "r")) == 0) {
    fprintf(stderr, "usage: harness STATES_FILE\n");
    return 2;
  }
#if NMEM > 0
  if (FN(_control)(q, dq, q_goal, k, r_d, 0, 1e-3, tau, 0, 0, 0, 0, memory_next, work) != -1)
    return 3;
#else
  if (FN(_control)(0, dq, q_goal, k, r_d, tau, 0, 0, 0, 0, work) != -1) return 3;
#endif
  if (FN(_cable_lengths)(q, l, 0) != -1) return 3;
  if (fscanf(in, "%ld", &count) != 1) return 4;
  for (s = 0; s < count; ++s) {
    if (read_vector(in, q, N) || read_vector(in, dq, N) || read_vector(in, q_goal, N)
        || read_vector(in, k, N) || read_vector(in, r_d, N)
#if NMEM > 0
        || read_vector(in, memory, NMEM) || fscanf(in, "%lf", &dt) != 1
#endif
        || fscanf(in, "%d", &use_case_gains) != 1) return 4;
#if NMEM > 0
    ret = FN(_control)(q, dq, q_goal, use_case_gains ? 0 : k, use_case_gains ? 0 : r_d, memory,
                       dt, tau, &alpha, &beta, j, &flags, memory_next, work);
    ret |= FN(_initial_memory)(q, q_goal, k, r_d, memory0, work);
#else
    ret = FN(_control)(q, dq, q_goal, use_case_gains ? 0 : k, use_case_gains ? 0 : r_d, tau,
                       &alpha, &beta, j, &flags, work);
#endif
    ret |= FN(_cable_lengths)(q, l, work);
    ret |= FN(_structure_matrix)(q, W, work);
    ret |= FN(_mass_matrix)(q, M, work);
    ret |= FN(_potential)(q, &V, work);
    ret |= FN(_p_matrix)(dq, P, work);
    ret |= FN(_a_matrix)(q, dq, A, work);
    printf("%d", ret);
    put(tau, N);
    printf(" %.17g %.17g", alpha, beta);
    put(j, NJ);
    printf(" %d", flags);
#if NMEM > 0
    put(memory_next, NMEM);
    put(memory0, NMEM);
#endif
    put(l, N);
    put(W, N * N);
    put(M, N * N);
    put(&V, 1);
    put(P, N * NJ);
    put(A, N * NJ);
    printf("\n");
  }
  fclose(in);
  free(work); free(q); free(dq); free(q_goal); free(k); free(r_d); free(tau); free(j);
  free(l); free(W); free(M); free(P); free(A);
#if NMEM > 0
  free(memory); free(memory_next); free(memory0);
#endif
  return 0;
}
