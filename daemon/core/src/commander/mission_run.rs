//! The uploaded mission and how far it has been flown: what outlives Mission mode (leaving
//! it pauses the mission; entering again resumes it).

use crate::mission::{MissionItem, MissionState, MissionStatus, REACHED_KEPT};

/// The uploaded mission and how far it has been flown.
#[derive(Debug, Clone, PartialEq)]
pub(super) struct MissionRun {
    pub(super) items: Vec<MissionItem>,
    pub(super) current: usize,
    pub(super) state: MissionState,
    /// Jumps done per item (for `DO_JUMP` repeats).
    pub(super) jumps: Vec<u32>,
    reached_count: u32,
    reached_recent: [u16; REACHED_KEPT],
}

impl MissionRun {
    pub(super) fn new() -> Self {
        Self {
            items: Vec::new(),
            current: 0,
            state: MissionState::NoMission,
            jumps: Vec::new(),
            reached_count: 0,
            reached_recent: [0; REACHED_KEPT],
        }
    }

    pub(super) fn item(&self) -> Option<MissionItem> {
        self.items.get(self.current).copied()
    }

    /// The current item is done: report it, go to the next.
    pub(super) fn reached(&mut self) {
        self.reached_recent[self.reached_count as usize % REACHED_KEPT] = self.current as u16;
        self.reached_count += 1;
        self.current += 1;
        if self.current >= self.items.len() {
            self.state = MissionState::Complete;
        }
    }

    /// Back to the first item, jump counters cleared.
    pub(super) fn restart(&mut self) {
        self.current = 0;
        self.jumps.iter_mut().for_each(|j| *j = 0);
        self.state = if self.items.is_empty() {
            MissionState::NoMission
        } else {
            MissionState::NotStarted
        };
    }

    pub(super) fn status(&self) -> MissionStatus {
        let total = self.items.len() as u16;
        MissionStatus {
            // Past the last item once complete, as MISSION_CURRENT says it.
            current: if self.state == MissionState::Complete {
                total
            } else {
                (self.current as u16).min(total.saturating_sub(1))
            },
            total,
            state: self.state,
            reached_count: self.reached_count,
            reached_recent: self.reached_recent,
        }
    }

    /// Leaving Mission mode before the end pauses it.
    pub(super) fn left(&mut self) {
        if self.state == MissionState::Active {
            self.state = MissionState::Paused;
        }
    }
}
