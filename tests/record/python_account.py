"""The Python client's counters on a stream with known holes (run by
test_record.cpp beside exodaq_test_seq_publisher):
    python3 python_account.py URL PREFIX READY_FILE
Subscribes to joint_state only (the status channel is read for the
accounting all the same), writes READY_FILE once subscribed, reads until a
second of silence after the first message, then prints the counters as JSON."""
import json
import sys

import exodaq


def main(url, prefix, ready):
    with exodaq.Subscriber(url, prefix=prefix, kinds=("joint_state",)) as sub:
        open(ready, "w").close()
        seqs = []
        got_any = False
        while True:
            m = sub.recv(timeout=1.0 if got_any else 30.0)
            if m is None:
                break
            got_any = True
            if m.kind != "joint_state":
                print("returned a %s message though only joint_state was asked" % m.kind)
                return 1
            seqs.append(m.msg.seq)
        print(json.dumps({"received": sub.received["joint_state"],
                          "repeated": sub.repeated["joint_state"],
                          "lost": sub.lost["joint_state"],
                          "skipped": sub.skipped["joint_state"],
                          "pending": sub.pending["joint_state"],
                          "status_returned": sub.received["status"],
                          "seqs": seqs}))
    return 0


if __name__ == "__main__":
    sys.exit(main(*sys.argv[1:]))
