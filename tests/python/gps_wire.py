"""What crosses a GPS's serial line, seen from outside: a relay between the autopilot and the
simulator's receiver that records both directions, and a u-blox receiver played by pyubx2.

Neither end of either is ours: every byte recorded is parsed by pyubx2 (UBX) or pynmeagps (NMEA),
and every message the pyubx2 receiver sends is built by pyubx2.
"""

import fcntl
import os
import select
import struct
import termios
import threading
import time
import tty
from io import BytesIO

from pyubx2 import ERR_RAISE, NMEA_PROTOCOL, POLL, SET, UBX_PROTOCOL, UBXMessage, UBXReader


# Linux's termios2 (asm-generic/termbits.h), which carries any baud as a number (BOTHER):
# serial libraries (the autopilot's serialport crate among them) set bauds through it, and the
# classic termios calls only see "BOTHER" then.
TCGETS2, TCSETS2 = 0x802C542A, 0x402C542B
TERMIOS2 = struct.Struct("<IIIIB19sII")
CBAUD, BOTHER = 0o010017, 0o010000


def baud_of(fd):
    """The line's output baud as the autopilot's end last set it (Linux termios2)."""
    return TERMIOS2.unpack(fcntl.ioctl(fd, TCGETS2, bytes(TERMIOS2.size)))[7]


def set_baud(fd, baud):
    """Sets the line's input and output baud (Linux termios2, BOTHER)."""
    iflag, oflag, cflag, lflag, line, cc, _, _ = TERMIOS2.unpack(
        fcntl.ioctl(fd, TCGETS2, bytes(TERMIOS2.size)))
    cflag = (cflag & ~CBAUD) | BOTHER
    fcntl.ioctl(fd, TCSETS2, TERMIOS2.pack(iflag, oflag, cflag, lflag, line, cc, baud, baud))


class GpsRelay:
    """A pseudo-terminal for the autopilot (`device`), joined to the simulator's GPS device
    (`far`): bytes go both ways as they come, each chunk recorded with the baud the autopilot's
    end was at, and that baud mirrored onto the simulator's line (which reads it back, as a
    receiver's UART would be at a baud or not)."""

    def __init__(self, far):
        self.master, slave = os.openpty()
        tty.setraw(self.master)
        # A baud no receiver is at, until the autopilot's end sets its own.
        set_baud(slave, 1200)
        self.device = os.ttyname(slave)
        self._slave = slave  # held until the autopilot opens it, so the line stays up
        self.far = os.open(far, os.O_RDWR | os.O_NOCTTY | os.O_NONBLOCK)
        tty.setraw(self.far)
        self.chunks = []  # (direction "to" or "from" the GPS, the line's baud, bytes), in order
        self.changes = 0
        self.running = True
        self.thread = threading.Thread(target=self._run, daemon=True)
        self.thread.start()

    def _mirror_baud(self):
        speed = baud_of(self.master)
        if baud_of(self.far) != speed:
            self.changes += 1
            set_baud(self.far, speed)
        return speed

    def _run(self):
        while self.running:
            ready = select.select([self.master, self.far], [], [], 0.01)[0]
            try:
                speed = self._mirror_baud()
            except (OSError, termios.error):
                time.sleep(0.01)  # the simulator's end has gone: the run is over
                continue
            for fd in ready:
                try:
                    data = os.read(fd, 4096)
                except OSError:
                    time.sleep(0.01)  # the autopilot has not opened its end yet
                    continue
                if fd == self.master:
                    self.chunks.append(("to", speed, data))
                    os.write(self.far, data)
                else:
                    self.chunks.append(("from", speed, data))
                    os.write(self.master, data)

    def sent(self):
        """Everything the autopilot sent."""
        return b"".join(data for d, _, data in self.chunks if d == "to")

    def heard_whole(self, power_on_baud, switch):
        """What the receiver sent while the line was at the receiver's baud: `power_on_baud`
        until the autopilot's message `switch` went by (its end's offset in what the autopilot
        sent, and the baud it sets; `None` for a receiver never moved), that baud after it. What
        it sent at another baud was misread."""
        to_end, switched_at = 0, None
        for k, (d, _, data) in enumerate(self.chunks):
            if d == "to":
                to_end += len(data)
                if switched_at is None and switch is not None and to_end >= switch[0]:
                    switched_at = k
        heard = b""
        for k, (d, baud, data) in enumerate(self.chunks):
            at = switch[1] if switched_at is not None and k > switched_at else power_on_baud
            if d == "from" and baud == at:
                heard += data
        return heard

    def close(self):
        self.running = False
        self.thread.join()
        for fd in (self.master, self._slave, self.far):
            os.close(fd)


def parse_all(data, msgmode=0):
    """Every UBX and NMEA message in `data` as pyubx2 parses it; any error raises."""
    reader = UBXReader(BytesIO(data), protfilter=UBX_PROTOCOL | NMEA_PROTOCOL,
                       quitonerror=ERR_RAISE, msgmode=msgmode)
    return [parsed for _, parsed in reader]


def parse_commands(data):
    """What an autopilot sent a receiver: its commands, parsed in pyubx2's SET mode."""
    return parse_all(data, msgmode=SET)


def ubx_frames(data):
    """Splits a stream of whole UBX frames (as a receiver reads them) into frames."""
    frames, i = [], 0
    while (i := data.find(b"\xb5\x62", i)) >= 0 and i + 6 <= len(data):
        n = 8 + int.from_bytes(data[i + 4:i + 6], "little")
        if i + n > len(data):
            break
        frames.append(data[i:i + n])
        i += n
    return frames, data[i:] if i >= 0 else b""


class Pyubx2Receiver:
    """A u-blox receiver played with pyubx2 on a pseudo-terminal (`device` for the autopilot):
    it answers MON-VER polls with its version (`protver`), parses every configuration message
    with pyubx2 (kept in `commands`) and acknowledges it, and sends what it is given to send."""

    def __init__(self, protver):
        self.master, slave = os.openpty()
        tty.setraw(self.master)
        self.device = os.ttyname(slave)
        self._slave = slave
        self.protver = protver
        self.commands = []
        self.pending = b""
        self.lock = threading.Lock()
        self.running = True
        self.thread = threading.Thread(target=self._run, daemon=True)
        self.thread.start()

    def send(self, data):
        with self.lock:
            os.write(self.master, data)

    def _answer(self, frame):
        parsed = UBXReader.parse(frame, msgmode=SET if len(frame) > 8 else POLL)
        self.commands.append(parsed)
        if parsed.identity == "MON-VER":
            # pyubx2 builds MON-VER's repeated extensions from its payload, not its keywords.
            fields = [(b"EXT CORE 1.00 (61b2dd)", 30), (b"00190000", 10),
                      (f"PROTVER={self.protver:.2f}".encode(), 30), (b"MOD=PYUBX2", 30)]
            reply = UBXMessage("MON", "MON-VER", 0,
                               payload=b"".join(text.ljust(n, b"\0") for text, n in fields))
        else:
            reply = UBXMessage("ACK", "ACK-ACK", 0, clsID=frame[2], msgID=frame[3])
        self.send(reply.serialize())

    def _run(self):
        while self.running:
            if not select.select([self.master], [], [], 0.01)[0]:
                continue
            try:
                data = os.read(self.master, 4096)
            except OSError:
                time.sleep(0.01)
                continue
            frames, self.pending = ubx_frames(self.pending + data)
            for f in frames:
                self._answer(f)

    def close(self):
        self.running = False
        self.thread.join()
        os.close(self.master)
        os.close(self._slave)
