//! What the ground stations ask of the host rather than the vehicle: parameters flown, saved
//! and reloaded, a reboot or shutdown; and the flight log's texts and parameter changes.

use super::to_vehicle::ToVehicle;
use crate::records::flight_ulog::UlogEvents;
use crate::records::param_file;
use flight_core::params::FlightParams;
use gcs::param_store::{Loaded, ParamStore, Unreadable};
use gcs::{GroundStation, HostAction, Outbox};
use mavlink::dialects::common::MavSeverity;
use tokio::sync::watch;
use tokio::task::JoinHandle;

use super::transport::Notices;

/// The host's side of the links.
pub(super) struct Host {
    /// The parameters the control loop flies with.
    params: watch::Sender<FlightParams>,
    /// The store to save (the saver task takes the latest).
    save: watch::Sender<Option<ParamStore>>,
    saving: JoinHandle<()>,
    /// The flight log's way in for texts and parameter changes.
    ulog: Option<UlogEvents>,
    /// The reboot or shutdown asked for.
    pub(super) exit: Option<HostAction>,
}

impl Host {
    /// Flies with `params`, saves stores as asked (saying failures on `notices`), logs to
    /// `ulog`.
    pub(super) fn new(
        params: watch::Sender<FlightParams>,
        ulog: Option<UlogEvents>,
        notices: Notices,
    ) -> Self {
        let (save, save_rx) = watch::channel(None::<ParamStore>);
        Self {
            params,
            save,
            saving: tokio::spawn(saver(save_rx, notices)),
            ulog,
            exit: None,
        }
    }

    /// Carries out the actions in `out`.
    pub(super) fn carry_out(
        &mut self,
        gcs: &mut GroundStation,
        vehicle: &ToVehicle,
        out: &mut Outbox,
    ) {
        for action in std::mem::take(&mut out.actions) {
            match action {
                HostAction::ParamsChanged => self.fly_with(gcs.parameters().values()),
                HostAction::SaveParams => {
                    self.save
                        .send_replace(Some(gcs.parameters().store().clone()));
                }
                HostAction::ReloadParams(to) => {
                    let loaded = match gcs.parameters().store().path() {
                        Some(path) => param_file::load(path, gcs.base_parameters())
                            .map_err(|e| Unreadable(format!("{e:#}"))),
                        None => Ok(Loaded {
                            store: gcs.parameters().store().clone(),
                            params: gcs.parameters().values().clone(),
                            warnings: Vec::new(),
                            from_previous_copy: false,
                        }),
                    };
                    gcs.params_reloaded(to, loaded, out);
                    self.fly_with(gcs.parameters().values());
                }
                HostAction::Reboot | HostAction::Shutdown => {
                    self.exit = Some(action);
                    // Disarmed (checked before): the loop may stop at once.
                    vehicle.stop();
                }
            }
        }
    }

    /// Hands the parameters `now` to the control loop, and logs in the flight log each one
    /// that changed.
    fn fly_with(&mut self, now: &FlightParams) {
        let before = self.params.send_replace(now.clone());
        let Some(log) = self.ulog.as_mut() else {
            return;
        };
        for (group, m) in FlightParams::metadata() {
            let value = now.get(group, m.key);
            if before.get(group, m.key) != value {
                log.param_changed(m.name, m.kind, value.unwrap_or(m.default));
            }
        }
    }

    /// Logs in the flight log what was told the operator (at `t_us`, the vehicle's clock).
    pub(super) fn log_said(&mut self, said: &mut Vec<(MavSeverity, String)>, t_us: u64) {
        let said = said.drain(..);
        if let Some(log) = self.ulog.as_mut() {
            for (severity, text) in said {
                log.said(severity as u8, t_us, &text);
            }
            log.flush();
        }
    }

    /// Says how many batches of texts and parameter changes the flight log lost.
    pub(super) fn report_lost(&self) {
        if let Some(lost) = self.ulog.as_ref().map(|u| u.lost).filter(|&n| n > 0) {
            tracing::warn!(
                lost,
                "flight log: batches of texts and parameter changes lost"
            );
        }
    }

    /// Waits for the last save; returns the reboot or shutdown asked for.
    pub(super) async fn finish(self) -> Option<HostAction> {
        drop(self.save);
        let _ = self.saving.await;
        self.exit
    }
}

/// Saves every store it is handed, the latest first (a burst of sets is one write), and says
/// so when a save fails.
async fn saver(mut stores: watch::Receiver<Option<ParamStore>>, notices: Notices) {
    while stores.changed().await.is_ok() {
        let Some(store) = stores.borrow_and_update().clone() else {
            continue;
        };
        let result = tokio::task::spawn_blocking(move || param_file::save(&store)).await;
        let failure = match result {
            Ok(Ok(())) => continue,
            Ok(Err(e)) => format!("{e:#}"),
            Err(e) => format!("saving parameters: {e}"),
        };
        tracing::error!("{failure}");
        let _ = notices
            .send((
                MavSeverity::MAV_SEVERITY_ERROR,
                format!("parameters not saved: {failure}"),
            ))
            .await;
    }
}
