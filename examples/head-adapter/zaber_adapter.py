#!/usr/bin/env python3
"""A head adapter for accelcal: drives two Zaber rotary axes over TCP for `--head exec:...`.

    accelcal station --head exec:"python3 examples/head-adapter/zaber_adapter.py HOST:PORT" ...

accelcal speaks its head protocol (version 2) on this program's standard input and output: one
request line in, one reply line out, in order (docs/src/line/heads.md, "The head protocol").
This adapter translates each request into Zaber ASCII commands (Zaber's ASCII Protocol Manual:
"Command Format", "Reply Format", "Warning Flags") for two rotary axes, alpha (the spindle) and
beta (the tilt). It uses the Python standard library only; a vendor's own library (zaber-motion,
a serial port package, an SDK over USB) would take the place of `ZaberLink` in the same few lines.

Diagnostics go to standard error: accelcal shows them to the operator, escaped.
"""

import argparse
import select
import socket
import sys

PROTOCOL_VERSION = 2
# Zaber warning flags that mean the axis cannot be trusted to have moved as told (ASCII Protocol
# Manual, "Warning Flags"): every F* fault, and WL (a limit sensor triggered unexpectedly).
FAULT_PREFIX = "F"
FAULTS_ALSO = {"WL"}
NOT_HOMED = "WH"


class HeadError(Exception):
    """A failure to report to accelcal as `ERR <reason>`."""


def axis_arg(text):
    """`D/A`: a device and an axis number, both 1..99."""
    try:
        device, axis = (int(x) for x in text.split("/"))
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r}: expected DEVICE/AXIS, e.g. 1/1")
    if not (1 <= device <= 99 and 1 <= axis <= 9):
        raise argparse.ArgumentTypeError(f"{text!r}: device 1..99, axis 1..9")
    return device, axis


class ZaberLink:
    """Zaber ASCII over TCP: one command line out, its reply line back."""

    def __init__(self, address, timeout_s):
        host, _, port = address.rpartition(":")
        self.sock = socket.create_connection((host, int(port)), timeout=timeout_s)
        self.buf = b""

    def _line(self):
        while b"\n" not in self.buf:
            chunk = self.sock.recv(4096)
            if not chunk:
                raise HeadError("the Zaber connection closed")
            self.buf += chunk
            if len(self.buf) > 4096:
                raise HeadError("a Zaber reply longer than 4096 bytes")
        line, _, self.buf = self.buf.partition(b"\n")
        return line.decode("ascii", "replace").strip()

    def command(self, name, device, axis, text, check_faults=True):
        """Sends `/D A text`, returns (status, flag, data) of its reply; RJ is an error, and so is
        a fault flag unless `check_faults` is False."""
        self.sock.sendall(f"/{device} {axis} {text}\n".encode("ascii"))
        while True:
            line = self._line()
            # Alerts (!) and info (#) messages are not replies to this command.
            if not line.startswith("@"):
                continue
            if ":" in line:  # an optional checksum, ":XX"
                line = line.rsplit(":", 1)[0]
            words = line[1:].split()
            if len(words) < 5 or int(words[0]) != device or int(words[1]) != axis:
                continue
            reply, status, flag = words[2:5]
            data = " ".join(words[5:])
            if reply == "RJ":
                raise HeadError(f"{name} (device {device} axis {axis}) rejected `{text}`: {data}")
            if check_faults and (flag.startswith(FAULT_PREFIX) or flag in FAULTS_ALSO):
                raise HeadError(f"{name} (device {device} axis {axis}) reports fault {flag}")
            return status, flag, data


class Head:
    def __init__(self, link, axes, deg_per_step):
        self.link = link
        self.axes = axes  # [("alpha", device, axis), ("beta", device, axis)]
        self.deg_per_step = deg_per_step

    def position(self):
        angles = []
        for name, d, a in self.axes:
            _, _, data = self.link.command(name, d, a, "get pos")
            angles.append(int(data) * self.deg_per_step)
        return angles

    def idle(self):
        """True when every axis is IDLE (faults raise)."""
        return all(self.link.command(n, d, a, "")[0] == "IDLE" for n, d, a in self.axes)

    def wait_idle(self, stop_requested=None):
        """Polls until both axes are IDLE; returns True when a STOP came in meanwhile."""
        while not self.idle():
            if stop_requested is not None and stop_requested():
                self.stop()
                return True
        return False

    def home(self):
        for name, d, a in self.axes:
            # Faults left over from an earlier run are cleared (its reply lists them); one that
            # persists shows again in the poll below, and is reported.
            _, _, cleared = self.link.command(name, d, a, "warnings clear", check_faults=False)
            if cleared.split()[1:]:
                print(f"{name} (device {d} axis {a}): cleared {' '.join(cleared.split()[1:])}", file=sys.stderr)
            _, flag, _ = self.link.command(name, d, a, "")
            if flag == NOT_HOMED:
                print(f"homing {name} (device {d} axis {a})", file=sys.stderr)
                self.link.command(name, d, a, "home")
        self.wait_idle()

    def move(self, alpha_deg, beta_deg, stop_requested):
        for (name, d, a), deg in zip(self.axes, (alpha_deg, beta_deg)):
            self.link.command(name, d, a, f"move abs {round(deg / self.deg_per_step)}")
        return self.wait_idle(stop_requested)

    def stop(self):
        for name, d, a in self.axes:
            self.link.command(name, d, a, "stop")
        self.wait_idle()


def fmt(angles):
    return f"{angles[0]:.9g} {angles[1]:.9g}"


def main():
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("address", help="the Zaber controller's HOST:PORT")
    p.add_argument("--alpha", type=axis_arg, default=(1, 1), help="alpha's DEVICE/AXIS [1/1]")
    p.add_argument("--beta", type=axis_arg, default=(2, 1), help="beta's DEVICE/AXIS [2/1]")
    p.add_argument("--deg-per-step", type=float, default=0.000234375,
                   help="degrees per microstep, from the stage's datasheet [0.000234375]")
    p.add_argument("--timeout-s", type=float, default=10.0, help="longest wait for a Zaber reply, s")
    args = p.parse_args()
    if not 0 < args.deg_per_step < 1:
        p.error("--deg-per-step must lie in (0, 1) degrees")
    link = ZaberLink(args.address, args.timeout_s)
    axes = [("alpha", *args.alpha), ("beta", *args.beta)]
    head = Head(link, axes, args.deg_per_step)
    pending = []  # request lines read while a move was under way

    def stop_requested():
        # A STOP sent while a MOVE waits is read here; other lines wait their turn.
        while select.select([sys.stdin], [], [], 0)[0]:
            line = sys.stdin.readline()
            if not line:
                return False
            if line.split() == ["STOP"]:
                return True
            pending.append(line)
        return False

    def reply(text):
        sys.stdout.write(text + "\n")
        sys.stdout.flush()

    while True:
        line = pending.pop(0) if pending else sys.stdin.readline()
        if not line:
            return 0  # accelcal closed our input: done
        words = line.split()
        if not words:
            continue
        try:
            req = words[0]
            if req == "HELLO":
                reply(f"HELLO {PROTOCOL_VERSION} zaber_adapter.py {args.address} "
                      f"alpha {args.alpha[0]}/{args.alpha[1]} beta {args.beta[0]}/{args.beta[1]}")
            elif req == "HOME":
                head.home()
                reply("OK " + fmt(head.position()))
            elif req == "MOVE" and len(words) == 3:
                stopped = head.move(float(words[1]), float(words[2]), stop_requested)
                reply("OK " + fmt(head.position()))
                if stopped:
                    reply("OK " + fmt(head.position()))
            elif req == "WHERE":
                state = "STILL" if head.idle() else "MOVING"
                reply(f"AT {fmt(head.position())} {state}")
            elif req == "STOP":
                head.stop()
                reply("OK " + fmt(head.position()))
            elif req in ("CHAMBER", "TEMP"):
                reply("ERR this rig has no thermal chamber")
            else:
                reply(f"ERR unknown request {req}")
        except (HeadError, ValueError, OSError) as e:
            reply(f"ERR {e}")


if __name__ == "__main__":
    sys.exit(main())
