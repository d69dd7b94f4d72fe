//! The force references a ROS 2 system commands on `/pneuflex/joint_commands` (ros2_control's topic-based
//! hardware interface publishes them: a `sensor_msgs/msg/JointState` with every joint's name and, for an
//! effort command interface, its effort), kept per joint with their arrival time. A joint's command is in
//! force while the last one arrived within the timeout; after that the scene's own reference applies again.
//! No DDS here: [`crate::node`] feeds it what it receives.

use crate::msg::JointState;

/// The latest command per joint and what was ignored.
#[derive(Clone, Debug)]
pub struct JointCommands {
    joints: Vec<String>,
    timeout_s: f64,
    /// Per joint: the commanded effort (N) and when it arrived (s, the loop's clock).
    latest: Vec<Option<(f64, f64)>>,
    /// Names of joints this node does not have, each reported once.
    unknown: Vec<String>,
    /// Messages taken (whatever they held).
    pub received: u64,
    /// Messages or entries refused (no effort, lengths that differ, a value that is not finite).
    pub refused: u64,
}

impl JointCommands {
    /// Commands for `joints` (the JointState names the node publishes), each in force for `timeout_s` after
    /// it arrived.
    pub fn new(joints: Vec<String>, timeout_s: f64) -> Self {
        let n = joints.len();
        Self {
            joints,
            timeout_s,
            latest: vec![None; n],
            unknown: Vec::new(),
            received: 0,
            refused: 0,
        }
    }

    /// Takes one message that arrived at `now_s`: each named joint's effort becomes its command. Returns
    /// what was ignored, in a sentence, the first time it happens (None otherwise): a message without
    /// efforts (a position or velocity command), arrays whose lengths differ from the names', a joint this
    /// node does not have, an effort that is not finite.
    pub fn take(&mut self, msg: &JointState, now_s: f64) -> Option<String> {
        self.received += 1;
        if msg.effort.is_empty() {
            self.refused += 1;
            return (self.refused == 1).then(|| {
                "a joint command without efforts is ignored: the node takes effort commands (the force \
                 reference, N) only"
                    .to_string()
            });
        }
        if msg.effort.len() != msg.name.len() {
            self.refused += 1;
            return Some(format!(
                "a joint command of {} names and {} efforts is ignored",
                msg.name.len(),
                msg.effort.len()
            ));
        }
        let mut said = None;
        for (name, &effort) in msg.name.iter().zip(&msg.effort) {
            match self.joints.iter().position(|j| j == name) {
                Some(i) if effort.is_finite() => self.latest[i] = Some((effort, now_s)),
                Some(_) => {
                    self.refused += 1;
                    said.get_or_insert_with(|| {
                        format!("joint `{name}`: an effort of {effort} N is ignored (not finite)")
                    });
                }
                None if !self.unknown.contains(name) => {
                    self.unknown.push(name.clone());
                    said.get_or_insert_with(|| {
                        format!(
                            "joint `{name}` is not one of this node's ({}): its command is ignored",
                            self.joints.join(", ")
                        )
                    });
                }
                None => {}
            }
        }
        said
    }

    /// Joint `i`'s commanded force at `now_s` (N), or None when no command for it arrived in the last
    /// `timeout_s`.
    pub fn effort(&self, i: usize, now_s: f64) -> Option<f64> {
        let (effort, at) = self.latest.get(i).copied().flatten()?;
        (now_s - at <= self.timeout_s).then_some(effort)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn command(names: &[&str], effort: &[f64]) -> JointState {
        JointState {
            name: names.iter().map(|s| s.to_string()).collect(),
            effort: effort.to_vec(),
            ..JointState::default()
        }
    }

    #[test]
    fn a_command_holds_for_its_timeout_per_joint() {
        let mut c = JointCommands::new(vec!["left".into(), "right".into()], 0.1);
        assert_eq!(c.effort(0, 0.0), None);
        assert_eq!(c.take(&command(&["right"], &[40.0]), 1.0), None);
        assert_eq!(c.effort(0, 1.0), None);
        assert_eq!(c.effort(1, 1.05), Some(40.0));
        assert_eq!(c.effort(1, 1.099), Some(40.0));
        assert_eq!(c.effort(1, 1.1001), None);
        // Both in one message, in any order; the last one wins.
        c.take(&command(&["right", "left"], &[10.0, 20.0]), 2.0);
        assert_eq!(
            (c.effort(0, 2.0), c.effort(1, 2.0)),
            (Some(20.0), Some(10.0))
        );
        assert_eq!(c.received, 2);
    }

    #[test]
    fn what_is_not_an_effort_command_is_ignored_and_said_once() {
        let mut c = JointCommands::new(vec!["cylinder".into()], 0.5);
        let position_only = JointState {
            name: vec!["cylinder".into()],
            position: vec![0.01],
            ..JointState::default()
        };
        assert!(c.take(&position_only, 0.0).unwrap().contains("effort"));
        assert_eq!(c.take(&position_only, 0.0), None);
        assert!(c.take(&command(&["cylinder"], &[1.0, 2.0]), 0.0).is_some());
        assert!(
            c.take(&command(&["cylinder"], &[f64::NAN]), 0.0)
                .unwrap()
                .contains("not finite")
        );
        let unknown = c.take(&command(&["elbow", "cylinder"], &[5.0, 30.0]), 0.0);
        assert!(
            unknown
                .unwrap()
                .contains("`elbow` is not one of this node's (cylinder)")
        );
        assert_eq!(c.take(&command(&["elbow"], &[5.0]), 0.0), None);
        assert_eq!(c.effort(0, 0.0), Some(30.0));
        assert_eq!(c.refused, 4);
    }
}
