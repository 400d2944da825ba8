"""JSBSim in-process, stepped in lockstep over UDP by `sitl --physics jsbsim`.

`sitl` writes this file, the model and its start file to a temporary root and runs it with a
Python that has the pinned PyPI `jsbsim`. It loads the model through JSBSim's Python API, binds
a UDP port on the loopback, prints `ready PORT` and then answers each request datagram with one
frame:

    request: u64 sequence number, then one f64 per input property (little-endian)
    reply:   the same sequence number, then one f64 per output property

Each request sets the inputs and runs JSBSim exactly `--frames` frames, so one sequence of
requests gives one trajectory, to the bit. It blocks while it waits (no polling), and ends when its
standard input closes: when `sitl` goes, however it goes (removing the temporary root if told). Anything wrong is said on stderr,
with exit status 2 (bad start) or 3 (bad request, JSBSim stopped).
"""

import argparse
import select
import shutil
import socket
import struct
import sys


def fail(status, message):
    print(f"jsbsim bridge: {message}", file=sys.stderr, flush=True)
    sys.exit(status)


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--root", required=True, help="JSBSim's root (holds aircraft/MODEL)")
    parser.add_argument("--model", required=True)
    parser.add_argument("--initfile", required=True, help="the start file (a path)")
    parser.add_argument("--rate", type=float, required=True, help="requests per second")
    parser.add_argument("--frames", type=int, default=1, help="JSBSim frames per request")
    parser.add_argument("--inputs", required=True, help="comma-separated input properties")
    parser.add_argument("--outputs", required=True, help="comma-separated output properties")
    parser.add_argument("--remove-root", action="store_true",
                        help="remove the root when standard input closes (sitl's temporary one)")
    args = parser.parse_args()
    inputs, outputs = args.inputs.split(","), args.outputs.split(",")

    try:
        import jsbsim
    except ImportError as e:
        fail(2, f"this Python has no jsbsim module ({e}); the pinned PyPI jsbsim==1.3.3 has it")
    fdm = jsbsim.FGFDMExec(args.root, None)
    fdm.set_debug_level(0)
    if not fdm.load_model(args.model):
        fail(2, f"JSBSim could not load the model {args.model} under {args.root}")
    if not fdm.load_ic(args.initfile, False):
        fail(2, f"JSBSim could not load the start file {args.initfile}")
    fdm.set_dt(1.0 / (args.rate * args.frames))
    if not fdm.run_ic():
        fail(2, "JSBSim could not initialise the model")
    properties = fdm.get_property_manager()
    unknown = [p for p in inputs + outputs if not properties.hasNode(p)]
    if unknown:
        fail(2, f"JSBSim has no properties {', '.join(unknown)}")
    # Nodes, not names: no lookup by string in the loop.
    input_nodes = [properties.get_node(p, False) for p in inputs]
    output_nodes = [properties.get_node(p, False) for p in outputs]
    request = struct.Struct(f"<Q{len(inputs)}d")
    reply = struct.Struct(f"<Q{len(outputs)}d")

    sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    sock.bind(("127.0.0.1", 0))
    print(f"ready {sock.getsockname()[1]}", flush=True)

    stdin = sys.stdin.fileno()
    while True:
        readable, _, _ = select.select([sock, stdin], [], [])
        if stdin in readable and not sys.stdin.buffer.read1(4096):
            # sitl has gone (or lets go): if it was killed, nobody else cleans up.
            if args.remove_root:
                shutil.rmtree(args.root, ignore_errors=True)
            return
        if sock not in readable:
            continue
        data, peer = sock.recvfrom(65536)
        if len(data) != request.size:
            fail(3, f"a request of {len(data)} bytes, {request.size} expected")
        sequence, *values = request.unpack(data)
        for node, value in zip(input_nodes, values):
            node.set_double_value(value)
        for _ in range(args.frames):
            if not fdm.run():
                fail(3, f"JSBSim stopped at t = {fdm.get_sim_time():.6f} s")
        sock.sendto(reply.pack(sequence, *(n.get_double_value() for n in output_nodes)), peer)


if __name__ == "__main__":
    main()
