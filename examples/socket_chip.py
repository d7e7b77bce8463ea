"""Put your own Ising machine behind the planner: a device driver that talks to a socket.

``SocketChip`` sends each stack of programs to a device as one JSON line and reads the spins
back; everything else (refusing programs that do not fit, seeds, timing, charging the calls
by the spec) comes from :class:`ising_backend.MachineBase`.  ``FakeDevice`` is a stand-in
device on localhost that anneals with the emulator, so the example runs anywhere:

    python examples/socket_chip.py

Wire protocol (one JSON object per line each way):
    request  {"h": [[...]], "J": [[[...]]], "num_reads": r, "seed": s}
    answer   {"spins": [[[+1/-1 ...]]]}  or  {"error": "what went wrong"}
"""

from __future__ import annotations

import json
import socket
import socketserver
import threading

import numpy as np

from ising_backend import ChipSpec, EmulatedChip, MachineBase


class DeviceError(RuntimeError):
    """The device answered with an error."""


class SocketChip(MachineBase):
    """An Ising machine reached over TCP at ``(host, port)``."""

    def __init__(self, host: str, port: int, spec: ChipSpec | None = None, seed: int | None = None,
                 timeout_s: float = 10.0):
        super().__init__(spec, seed)
        self.address = (host, int(port))
        self.timeout_s = timeout_s

    def _sample(self, h, J, num_reads, seed):
        request = {"h": h.astype(int).tolist(), "J": J.astype(int).tolist(), "num_reads": num_reads, "seed": seed}
        with socket.create_connection(self.address, timeout=self.timeout_s) as conn, conn.makefile("rwb") as f:
            f.write(json.dumps(request).encode() + b"\n")
            f.flush()
            answer = json.loads(f.readline())
        if "error" in answer:
            raise DeviceError(f"device at {self.address[0]}:{self.address[1]}: {answer['error']}")
        return np.asarray(answer["spins"], dtype=np.int8)


class FakeDevice:
    """A localhost device that anneals each request on an emulated chip (for tests and this demo)."""

    def __init__(self, spec: ChipSpec | None = None):
        chip = EmulatedChip(spec)

        class Handler(socketserver.StreamRequestHandler):
            def handle(self):
                req = json.loads(self.rfile.readline())
                try:
                    spins, _ = chip.anneal_batch(np.array(req["h"]), np.array(req["J"]), req["num_reads"], req["seed"])
                    answer = {"spins": spins.tolist()}
                except ValueError as exc:
                    answer = {"error": str(exc)}
                self.wfile.write(json.dumps(answer).encode() + b"\n")

        self.server = socketserver.ThreadingTCPServer(("127.0.0.1", 0), Handler)
        self.server.daemon_threads = True
        self.port = self.server.server_address[1]

    def __enter__(self):
        threading.Thread(target=self.server.serve_forever, daemon=True).start()
        return self

    def __exit__(self, *exc):
        self.server.shutdown()
        self.server.server_close()


if __name__ == "__main__":
    from mrmt_env.generation import generate_world
    from planners.pipeline import make_pipeline

    with FakeDevice() as device:
        chip = SocketChip("127.0.0.1", device.port)
        plan = make_pipeline("ising", chip=chip).plan(generate_world(0), seed=0)
        c = plan.compute
        print(f"plan valid: {plan.success}; route cost {sum(len(r.path) - 1 for r in plan.routes)}; "
              f"{c.chip_calls} chip calls = {c.chip_time_s * 1e3:.2f} ms and {c.accelerator_energy_j * 1e6:.1f} uJ "
              f"on the chip; host CPU {c.host_cpu_s * 1e3:.1f} ms")
