/* LD_PRELOAD probe for the end-to-end benchmark, on exodaqd's loop thread
 * ("exodaq-loop"):
 *
 * - the first absolute CLOCK_MONOTONIC deadline it sleeps to, written (ns) to
 *   $EXODAQ_BENCH_DEADLINE_FILE. The loop's deadline for cycle seq is then
 *   first + seq * period (overruns advance both together), so a subscriber can
 *   measure from the loop's deadline: the sim stamps mono_ns = source start +
 *   seq * period, a constant offset before that deadline.
 * - with $EXODAQ_BENCH_SPANS_FILE, where each cycle's time goes: the cycle
 *   (return from clock_nanosleep to the next call), the time inside sendmsg()
 *   (publishing from the loop), inside sem_post() (waking the publisher
 *   thread) and the rest (the cycle's own work), each as a histogram of 100 ns
 *   bins written at exit: "name bin_ns count" lines. Histograms, not samples:
 *   the probe adds a few KiB to the daemon, whatever the run's length.
 *
 * Other threads only pass through (one thread-local test). Not used for the
 * wake-up lateness runs. */
#define _GNU_SOURCE
#include <dlfcn.h>
#include <fcntl.h>
#include <semaphore.h>
#include <stdatomic.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/prctl.h>
#include <sys/socket.h>
#include <time.h>
#include <unistd.h>

typedef int (*clock_nanosleep_fn)(clockid_t, int, const struct timespec*, struct timespec*);
typedef ssize_t (*sendmsg_fn)(int, const struct msghdr*, int);
typedef int (*sem_post_fn)(sem_t*);

enum { kBins = 5000, kBinNs = 100 }; /* 0 .. 500 us; the last bin holds the rest */
enum { kCycle, kSend, kPost, kWork, kSpans };
static const char* const kSpanNames[kSpans] = {"cycle", "sendmsg", "sem_post", "work"};
static uint32_t g_hist[kSpans][kBins];
static atomic_int captured;
static __thread int t_role; /* 0: not looked at yet, 1: the loop thread, 2: another */
static __thread int64_t t_wake, t_send, t_post;

static int64_t now_ns(void) {
  struct timespec ts;
  clock_gettime(CLOCK_MONOTONIC, &ts);
  return (int64_t)ts.tv_sec * 1000000000LL + ts.tv_nsec;
}

static void* real_symbol(const char* name) {
  return dlsym(RTLD_NEXT, name);
}

static int is_loop_thread(void) {
  if (t_role == 0) {
    char name[17] = {0};
    prctl(PR_GET_NAME, name, 0, 0, 0);
    t_role = strcmp(name, "exodaq-loop") == 0 ? 1 : 2;
  }
  return t_role == 1;
}

static void add(int span, int64_t ns) {
  int64_t bin = ns / kBinNs;
  if (bin < 0) bin = 0;
  if (bin >= kBins) bin = kBins - 1;
  ++g_hist[span][bin];
}

static void write_first_deadline(const struct timespec* req) {
  const char* path = getenv("EXODAQ_BENCH_DEADLINE_FILE");
  if (path == NULL) return;
  char buf[32];
  const int n = snprintf(buf, sizeof buf, "%lld\n",
                         (long long)req->tv_sec * 1000000000LL + (long long)req->tv_nsec);
  const int fd = open(path, O_WRONLY | O_CREAT | O_TRUNC, 0644);
  if (fd >= 0) {
    if (write(fd, buf, (size_t)n) < 0) {
    }
    close(fd);
  }
}

int clock_nanosleep(clockid_t clock, int flags, const struct timespec* req, struct timespec* rem) {
  static clock_nanosleep_fn real;
  if (real == NULL) {
    void* sym = real_symbol("clock_nanosleep");
    memcpy(&real, &sym, sizeof real); /* POSIX: dlsym's object pointer is a function pointer */
  }
  if (clock != CLOCK_MONOTONIC || (flags & TIMER_ABSTIME) == 0 || !is_loop_thread()) {
    return real(clock, flags, req, rem);
  }
  if (!atomic_exchange(&captured, 1)) write_first_deadline(req);
  if (t_wake != 0) { /* the cycle that ends here */
    const int64_t cycle = now_ns() - t_wake;
    add(kCycle, cycle);
    add(kSend, t_send);
    add(kPost, t_post);
    add(kWork, cycle - t_send - t_post);
  }
  const int rc = real(clock, flags, req, rem);
  t_send = t_post = 0;
  t_wake = now_ns();
  return rc;
}

ssize_t sendmsg(int fd, const struct msghdr* msg, int flags) {
  static sendmsg_fn real;
  if (real == NULL) {
    void* sym = real_symbol("sendmsg");
    memcpy(&real, &sym, sizeof real);
  }
  if (!is_loop_thread()) return real(fd, msg, flags);
  const int64_t t0 = now_ns();
  const ssize_t rc = real(fd, msg, flags);
  t_send += now_ns() - t0;
  return rc;
}

int sem_post(sem_t* sem) {
  static sem_post_fn real;
  if (real == NULL) {
    void* sym = real_symbol("sem_post");
    memcpy(&real, &sym, sizeof real);
  }
  if (!is_loop_thread()) return real(sem);
  const int64_t t0 = now_ns();
  const int rc = real(sem);
  t_post += now_ns() - t0;
  return rc;
}

__attribute__((destructor)) static void write_spans(void) {
  const char* path = getenv("EXODAQ_BENCH_SPANS_FILE");
  if (path == NULL) return;
  FILE* f = fopen(path, "w");
  if (f == NULL) return;
  for (int s = 0; s < kSpans; ++s) {
    for (int b = 0; b < kBins; ++b) {
      if (g_hist[s][b] != 0) fprintf(f, "%s %d %u\n", kSpanNames[s], b * kBinNs, g_hist[s][b]);
    }
  }
  fclose(f);
}
