//! The MAVLink shell: `SERIAL_CONTROL` on `SERIAL_CONTROL_DEV_SHELL`, as PX4's nsh over MAVLink
//! (what QGroundControl's MAVLink console, MAVSDK's `shell` plugin, PX4's `mavlink_shell.py` and
//! MAVProxy's `nsh` module drive).
//!
//! The first message for the shell device opens a session for its sender (replacing another's)
//! and prints the prompt; its bytes are typed into it: printable characters are echoed and
//! make the line, `\n` or `\r` runs it ([`commands`]), backspace erases, Ctrl-C stops a
//! `listener` and clears the line; any other byte is ignored, and a line longer than
//! [`LINE_MAX`] is cut there. The output goes back in `SERIAL_CONTROL` replies (`REPLY`, at
//! most 70 bytes each) on the sender's link, unasked. An empty message without `RESPOND`
//! closes the session (PX4 closes on any message without it, but MAVSDK sends the first parts
//! of a long command without the flag). With signing on, only a trusted endpoint gets a shell.

mod commands;

use crate::link_rates::LinkId;
use crate::telemetry::Telemetry;
use crate::{GroundStation, Outbox, Outgoing};
use commands::Listener;
use mavlink::MavHeader;
use mavlink::dialects::common::*;
use std::collections::VecDeque;

/// The prompt, as NuttX's shell prints it (clients look for it).
const PROMPT: &str = "nsh> ";

/// The longest line typed (bytes).
pub const LINE_MAX: usize = 200;

/// Output sent per second at most (bytes): a shell's text, paced so that it cannot crowd out
/// telemetry, in bursts of at most [`OUTPUT_BURST`].
const OUTPUT_BYTES_PER_S: f64 = 10_000.0;

/// The largest burst of output in one poll (bytes).
const OUTPUT_BURST: f64 = 70.0 * 16.0;

/// Output waiting to be sent at most (bytes); more is dropped, and said.
const OUTPUT_MAX: usize = 16 * 1024;

/// One shell session.
#[derive(Debug, Default)]
pub(crate) struct Shell {
    /// Its client: link, system, component.
    peer: Option<(LinkId, u8, u8)>,
    line: String,
    /// The last byte typed was `\r` (a `\n` after it is the same line end).
    after_cr: bool,
    output: VecDeque<u8>,
    /// A `listener` printing samples.
    listener: Option<Listener>,
    /// A command passed to the vehicle has not been answered: the prompt waits for it.
    pending: bool,
    /// Output that may be sent now (bytes), and when it was last topped up (s).
    budget: (f64, f64),
}

impl Shell {
    /// Queues `text`; beyond [`OUTPUT_MAX`] waiting, it is dropped and a mark says so.
    fn print(&mut self, text: &str) {
        const DROPPED: &str = "\n[output dropped]\n";
        if self.output.len() + text.len() <= OUTPUT_MAX {
            self.output.extend(text.bytes());
        } else if !self
            .output
            .iter()
            .rev()
            .take(DROPPED.len())
            .copied()
            .eq(DROPPED.bytes().rev())
        {
            self.output.extend(DROPPED.bytes());
        }
    }

    /// The prompt, unless a listener or an answer is awaited.
    fn prompt(&mut self) {
        if self.listener.is_none() && !self.pending {
            self.print(PROMPT);
        }
    }
}

impl GroundStation {
    /// A `SERIAL_CONTROL` from `h` on `link`; `allowed`: the endpoint may have a shell (signing
    /// off, or a trusted endpoint).
    pub fn on_serial_control(
        &mut self,
        link: LinkId,
        h: &MavHeader,
        d: &SERIAL_CONTROL_DATA,
        allowed: bool,
        t: &Telemetry,
        out: &mut Outbox,
    ) {
        let for_us = d.target_system == 0 || d.target_system == self.system_id;
        if d.device != SerialControlDev::SERIAL_CONTROL_DEV_SHELL
            || d.flags
                .contains(SerialControlFlag::SERIAL_CONTROL_FLAG_REPLY)
            || !for_us
        {
            return;
        }
        let peer = (link, h.system_id as u8, h.component_id);
        if !allowed {
            tracing::warn!(
                ?peer,
                "MAVLink shell refused: endpoint not trusted, signing on"
            );
            reply(
                peer,
                b"shell refused: endpoint not trusted (signing is on)\n",
                out,
            );
            return;
        }
        let respond = d
            .flags
            .contains(SerialControlFlag::SERIAL_CONTROL_FLAG_RESPOND);
        let count = usize::from(d.count).min(d.data.len());
        if !respond && count == 0 {
            if self.shell.peer == Some(peer) {
                tracing::info!(?peer, "MAVLink shell closed");
                self.shell = Shell::default();
            }
            return;
        }
        if self.shell.peer != Some(peer) {
            tracing::info!(?peer, "MAVLink shell opened");
            self.shell = Shell {
                peer: Some(peer),
                ..Shell::default()
            };
            self.shell.print(PROMPT);
        }
        for &b in &d.data[..count] {
            self.type_byte(b, t, out);
        }
    }

    /// One byte typed into the shell.
    fn type_byte(&mut self, b: u8, t: &Telemetry, out: &mut Outbox) {
        let after_cr = std::mem::replace(&mut self.shell.after_cr, b == b'\r');
        match b {
            b'\n' if after_cr => {}
            b'\n' | b'\r' => {
                self.shell.print("\n");
                let line = std::mem::take(&mut self.shell.line);
                let text = self.run_line(&line, t, out);
                self.shell.print(&text);
                self.shell.prompt();
            }
            0x08 | 0x7f if self.shell.line.pop().is_some() => self.shell.print("\x08 \x08"),
            0x03 => {
                self.shell.listener = None;
                self.shell.line.clear();
                self.shell.print("^C\n");
                self.shell.prompt();
            }
            0x20..=0x7e if self.shell.line.len() < LINE_MAX => {
                self.shell.line.push(char::from(b));
                self.shell.print(std::str::from_utf8(&[b]).unwrap_or(""));
            }
            _ => {}
        }
    }

    /// The shell's turn of a poll: a listener's samples, then what is waiting, in replies.
    pub(crate) fn shell_poll(&mut self, now_s: f64, t: &Telemetry, out: &mut Outbox) {
        let Some(peer) = self.shell.peer else {
            return;
        };
        if let Some(l) = self.shell.listener.as_mut() {
            let (text, done) = l.sample(now_s, t);
            self.shell.print(&text);
            if done {
                self.shell.listener = None;
                self.shell.prompt();
            }
        }
        let (budget, last) = self.shell.budget;
        let budget = (budget + (now_s - last).max(0.0) * OUTPUT_BYTES_PER_S).min(OUTPUT_BURST);
        let n = self.shell.output.len().min(budget as usize);
        self.shell.budget = (budget - n as f64, now_s);
        if n > 0 {
            let bytes: Vec<u8> = self.shell.output.drain(..n).collect();
            reply(peer, &bytes, out);
        }
    }

    /// The answer to a command the shell of `to` passed to the vehicle (dropped if that
    /// session has ended).
    pub(crate) fn shell_answer(
        &mut self,
        to: crate::AckTo,
        result: Result<(), flight_core::commander::Denial>,
    ) {
        if self
            .shell
            .peer
            .is_none_or(|p| (p.1, p.2) != (to.system, to.component))
        {
            return;
        }
        let text = match result {
            Ok(()) => "accepted\n".to_owned(),
            Err(why) => format!("refused: {why}\n"),
        };
        self.shell.print(&text);
        self.shell.pending = false;
        self.shell.prompt();
    }
}

/// `bytes` to `peer` in `SERIAL_CONTROL` replies of at most 70 bytes.
fn reply(peer: (LinkId, u8, u8), bytes: &[u8], out: &mut Outbox) {
    for chunk in bytes.chunks(70) {
        let mut data = [0u8; 70];
        data[..chunk.len()].copy_from_slice(chunk);
        let m = MavMessage::SERIAL_CONTROL(SERIAL_CONTROL_DATA {
            baudrate: 0,
            timeout: 0,
            device: SerialControlDev::SERIAL_CONTROL_DEV_SHELL,
            flags: SerialControlFlag::SERIAL_CONTROL_FLAG_REPLY,
            count: chunk.len() as u8,
            data,
            target_system: peer.1,
            target_component: peer.2,
        });
        out.streamed.push((peer.0, Outgoing::Message(m)));
    }
}

#[cfg(test)]
mod tests;
