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

/// Bytes of output sent per poll at most (the rest waits for the next).
const OUTPUT_PER_POLL: usize = 70 * 32;

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
}

impl Shell {
    fn print(&mut self, text: &str) {
        self.output.extend(text.bytes());
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
                if self.shell.listener.is_none() {
                    self.shell.print(PROMPT);
                }
            }
            0x08 | 0x7f if self.shell.line.pop().is_some() => self.shell.print("\x08 \x08"),
            0x03 => {
                self.shell.listener = None;
                self.shell.line.clear();
                self.shell.print("^C\n");
                self.shell.print(PROMPT);
            }
            0x20..=0x7e if self.shell.line.len() < LINE_MAX => {
                self.shell.line.push(char::from(b));
                self.shell.output.push_back(b);
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
                self.shell.print(PROMPT);
            }
        }
        let n = self.shell.output.len().min(OUTPUT_PER_POLL);
        if n > 0 {
            let bytes: Vec<u8> = self.shell.output.drain(..n).collect();
            reply(peer, &bytes, out);
        }
    }

    /// The answer to a command the shell passed to the vehicle.
    pub(crate) fn shell_answer(&mut self, result: Result<(), flight_core::commander::Denial>) {
        let text = match result {
            Ok(()) => "accepted\n".to_owned(),
            Err(why) => format!("refused: {why}\n"),
        };
        self.shell.print(&text);
        self.shell.print(PROMPT);
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
