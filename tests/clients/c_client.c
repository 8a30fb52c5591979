/* A C client of the exodaq messages, built from the generated C bindings
 * (target exodaq_lcmtypes_c) the way a decoder lab would build one.
 *
 *   c_client files DIR                 decode DIR/<type>.bin of each type
 *   c_client subscribe URL PREFIX MS   subscribe to PREFIX + EXO_*, decode the
 *                                      first message of each type, wait at most MS ms
 *
 * Prints the canonical text of tests/clients/lcm_fixture.cpp for each message
 * and checks a few values itself. Exit 0 when all four decoded, 1 otherwise.
 */
#include <inttypes.h>
#include <lcm/lcm.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/time.h>

#include "exodaq_encoder_raw_t.h"
#include "exodaq_joint_state_t.h"
#include "exodaq_palm_pose_t.h"
#include "exodaq_status_t.h"

static const char* g_type;
static int g_failures;

static void p_i(const char* f, int i, long long v) {
  if (i < 0)
    printf("%s.%s=%lld\n", g_type, f, v);
  else
    printf("%s.%s[%d]=%lld\n", g_type, f, i, v);
}
static void p_d(const char* f, int i, double v) {
  uint64_t u;
  memcpy(&u, &v, sizeof u);
  if (i < 0)
    printf("%s.%s=0x%016" PRIx64 "\n", g_type, f, u);
  else
    printf("%s.%s[%d]=0x%016" PRIx64 "\n", g_type, f, i, u);
}
static void p_s(const char* f, int i, const char* v) {
  if (i < 0)
    printf("%s.%s=%s\n", g_type, f, v);
  else
    printf("%s.%s[%d]=%s\n", g_type, f, i, v);
}

#define I(field) p_i(#field, -1, (long long)m->field)
#define D(field) p_d(#field, -1, m->field)
#define S(field) p_s(#field, -1, m->field)
#define IA(field, n) \
  for (int i = 0; i < (n); ++i) p_i(#field, i, (long long)m->field[i])
#define DA(field, n) \
  for (int i = 0; i < (n); ++i) p_d(#field, i, m->field[i])
#define SA(field, n) \
  for (int i = 0; i < (n); ++i) p_s(#field, i, m->field[i])
#define CHECK(cond)                                           \
  do {                                                        \
    if (!(cond)) {                                            \
      fprintf(stderr, "c_client: check failed: %s\n", #cond); \
      ++g_failures;                                           \
    }                                                         \
  } while (0)

static void print_joint_state(const exodaq_joint_state_t* m) {
  g_type = "joint_state_t";
  I(utime), I(mono_ns), I(seq), I(run_id);
  SA(name, 6);
  DA(position, 6);
  DA(velocity, 6);
  IA(raw_count, 6);
  IA(homed, 6);
  IA(flags, 6);
  I(sample_flags);
  CHECK(m->seq == 4242424242LL);
  CHECK(strcmp(m->name[3], "elbow_flexion") == 0);
  CHECK(m->position[3] == -2.75);
  CHECK(m->raw_count[2] == 123456789012LL);
  CHECK(m->flags[2] == (EXODAQ_JOINT_STATE_T_JOINT_STALE | EXODAQ_JOINT_STATE_T_JOINT_HELD));
}

static void print_palm_pose(const exodaq_palm_pose_t* m) {
  g_type = "palm_pose_t";
  I(utime), I(mono_ns), I(seq), I(run_id);
  I(valid), I(invalid_reason);
  DA(position, 3);
  DA(orientation, 4);
  DA(elbow, 3);
  D(shoulder_manipulability), D(shoulder_manipulability_raw);
  I(near_singular);
  CHECK(!m->valid);
  CHECK(m->position[0] == 0.1234);
  CHECK(m->invalid_reason ==
        (EXODAQ_PALM_POSE_T_INVALID_UNHOMED | EXODAQ_PALM_POSE_T_INVALID_JOINT_FAULT));
}

static void print_encoder_raw(const exodaq_encoder_raw_t* m) {
  g_type = "encoder_raw_t";
  I(utime), I(mono_ns), I(seq), I(run_id);
  I(present), I(source_seq), I(source_seq_modulus);
  IA(position, 6);
  IA(modulus, 6);
  IA(index_position, 6);
  I(index_latched), I(index_count_valid), I(absolute), I(channel_fresh);
  I(board_state), I(board_errors), I(source_flags);
  I(wall_ns);
  CHECK(m->position[3] == -9007199254740992LL);
  CHECK(m->wall_ns == 1700000000123456789LL);
}

static void print_status(const exodaq_status_t* m) {
  g_type = "status_t";
  I(utime), I(mono_ns), I(seq), I(run_id);
  S(rig), I(state), S(message);
  I(window_cycles);
  D(period_p50_us), D(period_p99_us), D(period_max_us);
  D(lateness_p50_us), D(lateness_p99_us), D(lateness_max_us);
  D(work_p50_us), D(work_p99_us), D(work_max_us);
  I(overruns), I(cycles), I(publish_failures);
  S(source);
  I(frames), I(bad_frames), I(missing_samples), I(seq_gaps), I(duplicates), I(out_of_order);
  I(bus_errors), I(rx_overflows), I(bus_state), I(board_errors);
  I(clock_synchronised);
  D(clock_est_error_us), D(clock_max_error_us), D(clock_offset_us), D(utime_correction_us);
  I(clock_steps);
  S(config_path), S(config_sha256), S(calibration_path), S(calibration_sha256);
  S(calibration_provenance);
  I(reloads);
  I(foreign_run_id);
  SA(joint_name, 6);
  IA(homing, 6);
  IA(joint_flags, 6);
  IA(glitches, 6);
  IA(lost_count_events, 6);
  IA(stale_events, 6);
  IA(out_of_range_events, 6);
  CHECK(m->state == EXODAQ_STATUS_T_STATE_DEGRADED);
  CHECK(m->homing[4] == EXODAQ_STATUS_T_HOMING_REJECTED);
  CHECK(strcmp(m->rig, "sim-rig, bench 2") == 0);
}

/* Decodes one encoded message of the type named by `type`; 0 on success. */
static int decode_and_print(const char* type, const void* buf, int len) {
#define DECODE(T, print)                                                     \
  if (strcmp(type, #T) == 0) {                                               \
    exodaq_##T m;                                                            \
    int n = exodaq_##T##_decode(buf, 0, len, &m);                            \
    if (n != len) {                                                          \
      fprintf(stderr, "c_client: %s: decoded %d of %d bytes\n", #T, n, len); \
      if (n >= 0) exodaq_##T##_decode_cleanup(&m);                           \
      return 1;                                                              \
    }                                                                        \
    print(&m);                                                               \
    exodaq_##T##_decode_cleanup(&m);                                         \
    return 0;                                                                \
  }
  DECODE(joint_state_t, print_joint_state)
  DECODE(palm_pose_t, print_palm_pose)
  DECODE(encoder_raw_t, print_encoder_raw)
  DECODE(status_t, print_status)
#undef DECODE
  return 1;
}

static const char* const kTypes[4] = {"joint_state_t", "palm_pose_t", "encoder_raw_t", "status_t"};
static const char* const kChannels[4] = {"EXO_JOINT_STATE", "EXO_PALM_POSE", "EXO_ENCODER_RAW",
                                         "EXO_STATUS"};

static int from_files(const char* dir) {
  int bad = 0;
  for (int t = 0; t < 4; ++t) {
    char path[4096];
    snprintf(path, sizeof path, "%s/%s.bin", dir, kTypes[t]);
    FILE* f = fopen(path, "rb");
    if (!f) {
      fprintf(stderr, "c_client: cannot open %s\n", path);
      return 1;
    }
    static char buf[65536];
    const size_t n = fread(buf, 1, sizeof buf, f);
    fclose(f);
    bad += decode_and_print(kTypes[t], buf, (int)n);
  }
  return bad;
}

struct Seen {
  int got[4];
  int bad;
};

static void on_message(const lcm_recv_buf_t* rbuf, const char* channel, void* user) {
  struct Seen* seen = (struct Seen*)user;
  for (int t = 0; t < 4; ++t) {
    const size_t plen = strlen(channel) - strlen(kChannels[t]);
    if (strlen(channel) >= strlen(kChannels[t]) && strcmp(channel + plen, kChannels[t]) == 0) {
      if (seen->got[t]) return; /* the first of each type only */
      seen->got[t] = 1;
      seen->bad += decode_and_print(kTypes[t], rbuf->data, (int)rbuf->data_size);
      fflush(stdout);
      return;
    }
  }
}

static long long now_ms(void) {
  struct timeval tv;
  gettimeofday(&tv, NULL);
  return (long long)tv.tv_sec * 1000 + tv.tv_usec / 1000;
}

static int subscribe(const char* url, const char* prefix, long wait_ms) {
  lcm_t* lcm = lcm_create(url);
  if (!lcm) {
    fprintf(stderr, "c_client: cannot open LCM at %s\n", url);
    return 1;
  }
  struct Seen seen;
  memset(&seen, 0, sizeof seen);
  for (int t = 0; t < 4; ++t) {
    char channel[256];
    snprintf(channel, sizeof channel, "%s%s", prefix, kChannels[t]);
    lcm_subscribe(lcm, channel, on_message, &seen);
  }
  /* Tell the test driver we are listening: it starts the publisher after this. */
  fprintf(stderr, "c_client: subscribed\n");
  const long long end = now_ms() + wait_ms;
  int all = 0;
  while (!all && now_ms() < end) {
    lcm_handle_timeout(lcm, 100);
    all = seen.got[0] && seen.got[1] && seen.got[2] && seen.got[3];
  }
  lcm_destroy(lcm);
  if (!all) {
    fprintf(stderr, "c_client: not every type arrived within %ld ms\n", wait_ms);
    return 1;
  }
  return seen.bad;
}

int main(int argc, char** argv) {
  int rc;
  if (argc == 3 && strcmp(argv[1], "files") == 0) {
    rc = from_files(argv[2]);
  } else if (argc == 5 && strcmp(argv[1], "subscribe") == 0) {
    rc = subscribe(argv[2], argv[3], atol(argv[4]));
  } else {
    fprintf(stderr, "usage: c_client files DIR | subscribe URL PREFIX WAIT_MS\n");
    return 2;
  }
  return (rc || g_failures) ? 1 : 0;
}
