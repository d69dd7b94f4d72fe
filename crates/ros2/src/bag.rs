//! A rosbag2 recording as `ros2 bag record -s mcap` leaves it: a folder with `<folder>_0.mcap` (MCAP
//! profile `ros2`, each topic a channel with its type's `ros2msg` schema and `cdr` messages, log and
//! publish time the clock's reading in ns) and `metadata.yaml` (rosbag2's bag information, version 5:
//! what Humble writes and every later distribution reads). And the way back: the messages of a folder's
//! MCAP files by topic.

use std::collections::BTreeMap;
use std::fs::File;
use std::io::BufWriter;
use std::marker::PhantomData;
use std::path::{Path, PathBuf};

use crate::Ros2Error;
use crate::msg::Message;

/// The QoS a publisher of the recorded topic offered, as rosbag2 stores it (a YAML text inside the YAML):
/// history unknown (DDS discovery does not carry it), reliable, volatile, automatic liveliness, no
/// deadline, lifespan or lease (the largest duration).
const OFFERED_QOS: &str = "- history: 3\n  depth: 0\n  reliability: 1\n  durability: 2\n  deadline:\n    sec: 9223372036\n    nsec: 854775807\n  lifespan:\n    sec: 9223372036\n    nsec: 854775807\n  liveliness: 1\n  liveliness_lease_duration:\n    sec: 9223372036\n    nsec: 854775807\n  avoid_ros_namespace_conventions: false";

/// A topic of a bag being written, of message type `M`.
#[derive(Debug)]
pub struct Topic<M> {
    index: usize,
    _type: PhantomData<fn(M)>,
}

impl<M> Clone for Topic<M> {
    fn clone(&self) -> Self {
        *self
    }
}
impl<M> Copy for Topic<M> {}

#[derive(Clone, Debug)]
struct TopicEntry {
    name: String,
    msg_type: &'static str,
    channel: u16,
    count: u64,
}

/// What a written bag holds.
#[derive(Clone, Debug, PartialEq)]
pub struct BagSummary {
    /// The folder.
    pub dir: PathBuf,
    /// The MCAP file.
    pub file: PathBuf,
    /// Messages written, over every topic.
    pub message_count: u64,
    /// Each topic and its number of messages, in the order they were added.
    pub topics: Vec<(String, u64)>,
    /// The MCAP file's size, bytes.
    pub bytes: u64,
}

/// Writes a rosbag2 folder.
pub struct BagWriter {
    dir: PathBuf,
    file: PathBuf,
    mcap: mcap::Writer<BufWriter<File>>,
    schemas: BTreeMap<&'static str, u16>,
    topics: Vec<TopicEntry>,
    times: Option<(u64, u64)>,
    sequence: u32,
}

/// Whether `name` is a ROS 2 topic name (an absolute one, here): tokens of letters, digits and `_`, none
/// starting with a digit, none empty, no `__` (the rules of rcl's topic name validation).
pub fn valid_topic(name: &str) -> bool {
    let Some(rest) = name.strip_prefix('/') else {
        return false;
    };
    !name.contains("__")
        && rest.split('/').all(|t| {
            !t.is_empty()
                && !t.starts_with(|c: char| c.is_ascii_digit())
                && t.chars().all(|c| c.is_ascii_alphanumeric() || c == '_')
        })
}

/// `name` as one token of a topic name: other characters become `_`, a leading digit gets a `_` before.
pub fn topic_token(name: &str) -> String {
    let mut t: String = name
        .chars()
        .map(|c| if c.is_ascii_alphanumeric() { c } else { '_' })
        .collect();
    while t.contains("__") {
        t = t.replace("__", "_");
    }
    if t.is_empty() || t.starts_with(|c: char| c.is_ascii_digit()) {
        t.insert(0, 'n');
    }
    t
}

impl BagWriter {
    /// Creates the folder `dir` (which must not exist: a bag is written whole, never added to) and its
    /// MCAP file, named after the folder as rosbag2 names it.
    pub fn create(dir: &Path) -> Result<Self, Ros2Error> {
        let io = |path: &Path, what: &'static str| {
            let path = path.to_path_buf();
            move |e: std::io::Error| Ros2Error::Io {
                path,
                what,
                source: e,
            }
        };
        if dir.exists() {
            return Err(Ros2Error::Io {
                path: dir.to_path_buf(),
                what: "create the bag folder",
                source: std::io::Error::new(std::io::ErrorKind::AlreadyExists, "it exists already"),
            });
        }
        std::fs::create_dir_all(dir).map_err(io(dir, "create the bag folder"))?;
        let stem = dir
            .file_name()
            .map(|n| n.to_string_lossy().into_owned())
            .unwrap_or_else(|| "bag".into());
        let file = dir.join(format!("{stem}_0.mcap"));
        let out = File::create(&file).map_err(io(&file, "create"))?;
        let mcap = mcap::WriteOptions::new()
            .profile("ros2")
            .library(concat!("pneuflex-ros2 ", env!("CARGO_PKG_VERSION")))
            .compression(None) // rosbag2's default; zstd at opt-level 0 (debug builds) tripled the write time
            .create(BufWriter::new(out))
            .map_err(|e| Ros2Error::Mcap {
                path: file.clone(),
                source: e,
            })?;
        Ok(Self {
            dir: dir.to_path_buf(),
            file,
            mcap,
            schemas: BTreeMap::new(),
            topics: Vec::new(),
            times: None,
            sequence: 0,
        })
    }

    fn mcap_err(&self) -> impl Fn(mcap::McapError) -> Ros2Error + '_ {
        |source| Ros2Error::Mcap {
            path: self.file.clone(),
            source,
        }
    }

    /// Adds topic `name` of message type `M`.
    pub fn topic<M: Message>(&mut self, name: &str) -> Result<Topic<M>, Ros2Error> {
        if !valid_topic(name) {
            return Err(Ros2Error::Topic(format!(
                "`{name}`: not a ROS 2 topic name (/ then tokens of letters, digits and _, none starting with a digit)"
            )));
        }
        if self.topics.iter().any(|t| t.name == name) {
            return Err(Ros2Error::Topic(format!("`{name}` added twice")));
        }
        let schema = match self.schemas.get(M::TYPE) {
            Some(&id) => id,
            None => {
                let id = self
                    .mcap
                    .add_schema(M::TYPE, "ros2msg", M::definition().as_bytes())
                    .map_err(|source| Ros2Error::Mcap {
                        path: self.file.clone(),
                        source,
                    })?;
                self.schemas.insert(M::TYPE, id);
                id
            }
        };
        let metadata = BTreeMap::from([("offered_qos_profiles".to_string(), OFFERED_QOS.into())]);
        let channel = self
            .mcap
            .add_channel(schema, name, "cdr", &metadata)
            .map_err(self.mcap_err())?;
        self.topics.push(TopicEntry {
            name: name.into(),
            msg_type: M::TYPE,
            channel,
            count: 0,
        });
        Ok(Topic {
            index: self.topics.len() - 1,
            _type: PhantomData,
        })
    }

    /// Writes `msg` on `topic` at `t_ns` of the clock (log and publish time alike).
    pub fn write<M: Message>(
        &mut self,
        topic: Topic<M>,
        t_ns: u64,
        msg: &M,
    ) -> Result<(), Ros2Error> {
        let entry = &mut self.topics[topic.index];
        entry.count += 1;
        let header = mcap::records::MessageHeader {
            channel_id: entry.channel,
            sequence: self.sequence,
            log_time: t_ns,
            publish_time: t_ns,
        };
        self.sequence = self.sequence.wrapping_add(1);
        self.times = Some(match self.times {
            None => (t_ns, t_ns),
            Some((a, b)) => (a.min(t_ns), b.max(t_ns)),
        });
        let data = msg.encode();
        self.mcap
            .write_to_known_channel(&header, &data)
            .map_err(|source| Ros2Error::Mcap {
                path: self.file.clone(),
                source,
            })
    }

    /// Ends the MCAP file (its summary and index) and writes `metadata.yaml`.
    pub fn finish(mut self) -> Result<BagSummary, Ros2Error> {
        self.mcap.finish().map_err(|source| Ros2Error::Mcap {
            path: self.file.clone(),
            source,
        })?;
        let file = self.file.clone();
        let mut out = self.mcap.into_inner();
        std::io::Write::flush(&mut out).map_err(|e| Ros2Error::Io {
            path: file.clone(),
            what: "write",
            source: e,
        })?;
        drop(out);
        let (start, end) = self.times.unwrap_or((0, 0));
        let count: u64 = self.topics.iter().map(|t| t.count).sum();
        let file_name = file
            .file_name()
            .map(|n| n.to_string_lossy().into_owned())
            .unwrap_or_default();
        let mut y = String::from(
            "rosbag2_bagfile_information:\n  version: 5\n  storage_identifier: mcap\n",
        );
        y += &format!("  duration:\n    nanoseconds: {}\n", end - start);
        y += &format!("  starting_time:\n    nanoseconds_since_epoch: {start}\n");
        y += &format!("  message_count: {count}\n  topics_with_message_count:\n");
        for t in &self.topics {
            y += &format!(
                "    - topic_metadata:\n        name: {}\n        type: {}\n        serialization_format: cdr\n        offered_qos_profiles: {:?}\n      message_count: {}\n",
                t.name, t.msg_type, OFFERED_QOS, t.count
            );
        }
        y += "  compression_format: \"\"\n  compression_mode: \"\"\n";
        y += &format!("  relative_file_paths:\n    - {file_name}\n");
        y += &format!(
            "  files:\n    - path: {file_name}\n      starting_time:\n        nanoseconds_since_epoch: {start}\n      duration:\n        nanoseconds: {}\n      message_count: {count}\n",
            end - start
        );
        let meta = self.dir.join("metadata.yaml");
        std::fs::write(&meta, y).map_err(|e| Ros2Error::Io {
            path: meta.clone(),
            what: "write",
            source: e,
        })?;
        let bytes = std::fs::metadata(&file).map(|m| m.len()).unwrap_or(0);
        Ok(BagSummary {
            dir: self.dir,
            file,
            message_count: count,
            topics: self.topics.into_iter().map(|t| (t.name, t.count)).collect(),
            bytes,
        })
    }
}

/// One message as read back: its time and its CDR bytes.
#[derive(Clone, Debug, PartialEq)]
pub struct Recorded {
    /// Log time, ns.
    pub t_ns: u64,
    /// The message's bytes, encapsulation header first.
    pub data: Vec<u8>,
}

/// A bag's messages by topic: each topic's type and its messages in log-time order.
#[derive(Clone, Debug, Default)]
pub struct BagContents {
    /// The folder (or the MCAP file) read.
    pub path: PathBuf,
    /// Topic name to (type, messages).
    pub topics: BTreeMap<String, (String, Vec<Recorded>)>,
}

impl BagContents {
    /// Topic `name`'s messages, checked to be of type `M`.
    pub fn messages<M: Message>(&self, name: &str) -> Result<&[Recorded], Ros2Error> {
        let (ty, msgs) = self.topics.get(name).ok_or_else(|| Ros2Error::Bag {
            path: self.path.clone(),
            message: format!(
                "no topic `{name}` (it has {})",
                self.topics.keys().cloned().collect::<Vec<_>>().join(", ")
            ),
        })?;
        if ty != M::TYPE {
            return Err(Ros2Error::Bag {
                path: self.path.clone(),
                message: format!("topic `{name}` is of type {ty}, not {}", M::TYPE),
            });
        }
        Ok(msgs)
    }
}

/// The MCAP files of a rosbag2 folder, in its `metadata.yaml`'s order (`relative_file_paths`); a path to
/// an `.mcap` file is that file.
pub fn bag_files(path: &Path) -> Result<Vec<PathBuf>, Ros2Error> {
    if path.is_file() {
        return Ok(vec![path.to_path_buf()]);
    }
    if path.extension().is_some_and(|e| e == "mcap") {
        return Err(Ros2Error::Io {
            path: path.to_path_buf(),
            what: "read",
            source: std::io::Error::new(std::io::ErrorKind::NotFound, "no such file"),
        });
    }
    let meta = path.join("metadata.yaml");
    let text = std::fs::read_to_string(&meta).map_err(|e| Ros2Error::Io {
        path: meta.clone(),
        what: "read (a rosbag2 folder has one)",
        source: e,
    })?;
    if !text.contains("storage_identifier: mcap") {
        return Err(Ros2Error::Bag {
            path: meta,
            message: "not an MCAP bag (storage_identifier is not mcap): convert it with `ros2 bag convert`".into(),
        });
    }
    let mut files = Vec::new();
    let mut in_list = false;
    for line in text.lines() {
        let l = line.trim();
        if l == "relative_file_paths:" {
            in_list = true;
        } else if in_list {
            match l.strip_prefix("- ") {
                Some(f) => files.push(
                    path.join(
                        Path::new(f.trim().trim_matches('"'))
                            .file_name()
                            .unwrap_or_default(),
                    ),
                ),
                None => in_list = false,
            }
        }
    }
    if files.is_empty() {
        return Err(Ros2Error::Bag {
            path: meta,
            message: "no relative_file_paths".into(),
        });
    }
    Ok(files)
}

/// The largest MCAP file read, bytes (a bag of an hour at 1 kHz of our topics is ~1 GB).
pub const MAX_BAG_BYTES: u64 = 4 << 30;

/// Reads every message of a rosbag2 folder (or one MCAP file), checking each topic is CDR-encoded.
pub fn read_bag(path: &Path) -> Result<BagContents, Ros2Error> {
    let mut out = BagContents {
        path: path.to_path_buf(),
        topics: BTreeMap::new(),
    };
    for file in bag_files(path)? {
        let io = |e: std::io::Error| Ros2Error::Io {
            path: file.clone(),
            what: "read",
            source: e,
        };
        let size = std::fs::metadata(&file).map_err(io)?.len();
        if size > MAX_BAG_BYTES {
            return Err(Ros2Error::Bag {
                path: file.clone(),
                message: format!("{size} bytes: larger than the {MAX_BAG_BYTES} bytes read"),
            });
        }
        let bytes = std::fs::read(&file).map_err(io)?;
        let stream = mcap::MessageStream::new(&bytes).map_err(|source| Ros2Error::Mcap {
            path: file.clone(),
            source,
        })?;
        for m in stream {
            let m = m.map_err(|source| Ros2Error::Mcap {
                path: file.clone(),
                source,
            })?;
            if m.channel.message_encoding != "cdr" {
                return Err(Ros2Error::Bag {
                    path: file.clone(),
                    message: format!(
                        "topic `{}` is encoded as `{}`, not cdr",
                        m.channel.topic, m.channel.message_encoding
                    ),
                });
            }
            let ty = m
                .channel
                .schema
                .as_ref()
                .map(|s| s.name.clone())
                .unwrap_or_default();
            let entry = out
                .topics
                .entry(m.channel.topic.clone())
                .or_insert_with(|| (ty, Vec::new()));
            entry.1.push(Recorded {
                t_ns: m.log_time,
                data: m.data.into_owned(),
            });
        }
    }
    for (_, msgs) in out.topics.values_mut() {
        msgs.sort_by_key(|m| m.t_ns);
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn topic_names_follow_the_ros_2_rules() {
        assert!(valid_topic("/pneuflex/pressures/left/a"));
        assert!(!valid_topic("/pneuflex/2nd"));
        assert!(!valid_topic("/pneuflex/a-b"));
        assert!(!valid_topic("pneuflex"));
        assert!(!valid_topic("/a//b"));
        assert_eq!(topic_token("finger-1"), "finger_1");
        assert_eq!(topic_token("2nd"), "n2nd");
    }
}
