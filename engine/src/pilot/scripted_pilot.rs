//! The pilot of a drone with a scenario mission: once pilots are released it loads the
//! mission, arms and starts it, as a pilot script would; while the autopilot refuses (an
//! arming check, no position fix yet) it tries again every [`RETRY_PERIOD_S`].

use crate::autopilot::mission::MissionPlan;
use crate::autopilot::navigator::{Command, Rejection};
use crate::events::EventKind;

/// Sim seconds between two attempts to start the mission.
pub const RETRY_PERIOD_S: f64 = 1.0;

/// A scripted pilot: the mission it flies (expanded by [`super::scripted::expand`]) and how
/// far it got.
#[derive(Clone, Debug)]
pub struct ScriptedPilot {
    mission: MissionPlan,
    started: bool,
    /// Sim time of the next attempt, s.
    next_try_s: f64,
}

impl ScriptedPilot {
    /// A pilot that will fly `mission` (first attempt as soon as it is released).
    pub fn new(mission: MissionPlan) -> Self {
        Self { mission, started: false, next_try_s: 0.0 }
    }

    /// The mission is running (the autopilot accepted all three commands).
    pub fn started(&self) -> bool {
        self.started
    }

    /// At sim time `t_s`: when `released` and due, sends LoadMission, Arm and StartMission
    /// through `command` (stopping at the first refusal). A refusal is returned as the
    /// `CommandRejected` event to report, and the next attempt is [`RETRY_PERIOD_S`] later.
    pub fn fly(
        &mut self,
        t_s: f64,
        released: bool,
        mut command: impl FnMut(Command) -> Result<(), Rejection>,
    ) -> Option<EventKind> {
        if !released || self.started || t_s < self.next_try_s {
            return None;
        }
        let result = command(Command::LoadMission(self.mission.clone()))
            .and_then(|()| command(Command::Arm))
            .and_then(|()| command(Command::StartMission));
        match result {
            Ok(()) => {
                self.started = true;
                None
            }
            Err(e) => {
                self.next_try_s = t_s + RETRY_PERIOD_S;
                Some(EventKind::CommandRejected { command: "startMission".into(), reason: e.to_string() })
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::autopilot::mission::MissionItem;

    fn pilot() -> ScriptedPilot {
        ScriptedPilot::new(MissionPlan { items: vec![MissionItem::Takeoff { alt_rel_home_m: 10.0 }], speed_mps: 5.0 })
    }

    /// Records the commands' names; refuses Arm while `refuse_arm`.
    fn autopilot<'a>(
        sent: &'a mut Vec<&'static str>,
        refuse_arm: bool,
    ) -> impl FnMut(Command) -> Result<(), Rejection> + 'a {
        move |c| {
            let name = match c {
                Command::LoadMission(_) => "load",
                Command::Arm => "arm",
                Command::StartMission => "start",
                _ => "other",
            };
            sent.push(name);
            if refuse_arm && name == "arm" { Err(Rejection::ArmingCheck("no fix".into())) } else { Ok(()) }
        }
    }

    #[test]
    fn nothing_is_sent_before_the_pilots_are_released() {
        let mut sent = Vec::new();
        let mut p = pilot();
        assert_eq!(p.fly(5.0, false, autopilot(&mut sent, false)), None);
        assert!(sent.is_empty() && !p.started());
    }

    #[test]
    fn a_released_pilot_loads_arms_and_starts_once() {
        let mut sent = Vec::new();
        let mut p = pilot();
        assert_eq!(p.fly(0.5, true, autopilot(&mut sent, false)), None);
        assert!(p.fly(0.6, true, autopilot(&mut sent, false)).is_none());
        assert_eq!(sent, ["load", "arm", "start"]);
        assert!(p.started());
    }

    #[test]
    fn a_refused_arm_is_reported_and_retried_a_second_later() {
        let mut sent = Vec::new();
        let mut p = pilot();
        let event = p.fly(2.0, true, autopilot(&mut sent, true));
        assert_eq!(
            event,
            Some(EventKind::CommandRejected {
                command: "startMission".into(),
                reason: "arming refused: no fix".into()
            })
        );
        assert_eq!(sent, ["load", "arm"]);
        // Not again before 3.0 s.
        assert_eq!(p.fly(2.0 + RETRY_PERIOD_S - 0.001, true, autopilot(&mut sent, false)), None);
        assert_eq!(sent.len(), 2);
        assert_eq!(p.fly(2.0 + RETRY_PERIOD_S, true, autopilot(&mut sent, false)), None);
        assert_eq!(sent, ["load", "arm", "load", "arm", "start"]);
        assert!(p.started());
    }
}
