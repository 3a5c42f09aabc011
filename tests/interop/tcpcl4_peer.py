"""Drive the RFC 9174 author's TCPCLv4 agent (github BrianSipos/dtn-demo-agent, package ``tcpcl``) as
an independent peer for tests/interop/test_tcpcl4_interop.py. Runs under the Python that has that
agent's dependencies (D-Bus, GLib, scapy; scripts/setup_tcpcl4_peer.sh), not the project's venv:

    python tcpcl4_peer.py --bus ADDR (--listen | --connect) HOST PORT --segment-mru N --tx-segment N
                          [--send FILE...] --expect N --out DIR --timeout S

It sends each ``--send`` file as one bundle once the session is up, writes every bundle it receives
to ``DIR/<n>.bin``, ends the session (SESS_TERM) when it has sent and received what it should, and
prints one JSON line: what it sent, received and negotiated. Nothing of the agent is copied here:
it is imported and called through its own methods.
"""

from __future__ import annotations

import argparse
import json
import logging
import sys
import time
from pathlib import Path


def main() -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("--bus", required=True)
    mode = ap.add_mutually_exclusive_group(required=True)
    mode.add_argument("--listen", nargs=2, metavar=("HOST", "PORT"))
    mode.add_argument("--connect", nargs=2, metavar=("HOST", "PORT"))
    ap.add_argument("--segment-mru", type=int, required=True)
    ap.add_argument("--tx-segment", type=int, required=True)
    ap.add_argument("--send", nargs="*", default=[])
    ap.add_argument("--expect", type=int, default=0)
    ap.add_argument("--out", type=Path, required=True)
    ap.add_argument("--timeout", type=float, default=60)
    a = ap.parse_args()
    logging.basicConfig(level=logging.WARNING)

    from dbus.mainloop.glib import DBusGMainLoop
    DBusGMainLoop(set_as_default=True)
    from gi.repository import GLib
    from tcpcl.agent import Agent
    from tcpcl.config import Config, ConnectConfig, ListenConfig

    cfg = Config()
    cfg.bus_addr = a.bus
    cfg.node_id = "ipn:9.0"
    cfg.tls_enable = False
    cfg.keepalive_time = 10
    cfg.segment_size_mru = a.segment_mru
    cfg.segment_size_tx_initial = a.tx_segment
    if a.listen:
        cfg.init_listen = [ListenConfig(address=a.listen[0], port=int(a.listen[1]))]
    else:
        cfg.init_connect = [ConnectConfig(address=a.connect[0], port=int(a.connect[1]))]
    agent = Agent(cfg)
    a.out.mkdir(parents=True, exist_ok=True)
    state = {"sent": 0, "received": 0, "sess": None, "queued": False, "params": {}, "terminated": False,
             "states": [], "results": []}
    loop = GLib.MainLoop()
    t0 = time.monotonic()

    def poll() -> bool:
        if time.monotonic() - t0 > a.timeout:
            state["error"] = "timeout"
            loop.quit()
            return False
        paths = list(agent.get_connections())
        if state["sess"] is None and paths:
            state["sess"] = h = agent.handler_for_path(str(paths[0]))
            finished = h.send_bundle_finished  # the agent's own signal, called when a transfer ends

            def counted(bid, length, result, finished=finished):
                state["results"].append(str(result))
                return finished(bid, length, result)
            h.send_bundle_finished = counted
        s = state["sess"]
        if s is None:
            return True
        if not paths:  # the session is over (closed by either side) and removed from the agent
            state["states"].append("closed")
            loop.quit()
            return False
        st = str(s.get_session_state())
        if not state["states"] or state["states"][-1] != st:
            state["states"].append(st)
        if st == "established" and not state["queued"]:
            state["params"] = {str(k): (int(v) if isinstance(v, int) else str(v))
                               for k, v in dict(s.get_session_parameters()).items()}
            for f in a.send:
                s.send_bundle_file(f)
            state["queued"] = True
        for bid in list(s.recv_bundle_get_queue()):
            data = bytes(s.recv_bundle_pop_data(bid))
            state["received"] += 1
            (a.out / f"{state['received']:04d}.bin").write_bytes(data)
        state["sent"] = state["results"].count("success")
        done = state["queued"] and state["sent"] == len(a.send) and state["received"] >= a.expect
        if done and not state["terminated"] and st == "established":
            state["terminated"] = True
            s.terminate()
        if st == "closed" or (state["terminated"] and not list(agent.get_connections())):
            loop.quit()
            return False
        return True

    GLib.timeout_add(50, poll)
    loop.run()
    state["sent"] = state["results"].count("success")
    print(json.dumps({k: state[k] for k in ("sent", "received", "params", "states", "results")} | {"error": state.get("error")}))
    return 0 if state.get("error") is None else 1


if __name__ == "__main__":
    sys.exit(main())
