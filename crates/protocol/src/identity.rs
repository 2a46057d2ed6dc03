//! Telling the graph's own publishers from anyone else's.
//!
//! Any ROS 2 node may publish on the graph's topics, and a well-formed sample with the
//! right stamp from a stray publisher looks exactly like the simulator's. What tells them
//! apart is the writer: every sample carries its writer's GID, and every ROS 2 participant
//! announces on `ros_discovery_info` which node owns which writers (rmw_dds_common's
//! `ParticipantEntitiesInfo`). A node of the graph keeps a [`WriterDirectory`] of those
//! announcements and accepts a topic's samples only from the nodes [`Trusted`] names
//! (by default the node the graph file says publishes the topic). A sample whose writer
//! has not been announced yet waits in a [`Quarantine`], bounded, until the announcement
//! arrives; samples of writers announced as other nodes are dropped and counted.
//!
//! This is no security: a node may take any name. It keeps strays and misconfigured peers
//! out of a run; SROS2 access control is what keeps an adversary out.

use std::collections::{HashMap, VecDeque};

/// A DDS entity's global identifier: its 16-byte GUID (rmw_dds_common `Gid` since Iron).
pub type Gid = [u8; 16];

/// Which node owns each announced writer, from the `ros_discovery_info` samples seen.
///
/// Bounded, since any participant may announce anything: a writer its participant stops
/// naming is kept for the last [`WriterDirectory::DEPARTED_KEPT`] such departures, and at
/// most [`WriterDirectory::WRITERS_KEPT`] writers are known at once; a writer announced
/// beyond that is refused (counted), so a flood of fresh GIDs cannot push out the graph's
/// own writers, which were announced first.
#[derive(Debug, Default, Clone)]
pub struct WriterDirectory {
    /// Fully qualified node name of each writer announced now or departed recently.
    node_of_writer: HashMap<Gid, String>,
    /// The writers each participant's last announcement named.
    writers_of_participant: HashMap<Gid, Vec<Gid>>,
    /// The participant whose last announcement names each writer.
    announcer: HashMap<Gid, Gid>,
    /// Writers no longer named by their participant, oldest first.
    departed: VecDeque<Gid>,
    /// Writers refused because the directory was full.
    refused: u64,
}

impl WriterDirectory {
    /// Departed writers remembered: a node's samples written before it left are read
    /// within moments, so the last few thousand departures are plenty.
    pub const DEPARTED_KEPT: usize = 4096;
    /// Writers known at once (announced now or departed recently).
    pub const WRITERS_KEPT: usize = 16384;

    /// Takes a participant's announcement: `nodes` as (fully qualified name, writer
    /// GIDs). A writer it names is now that node's. A writer it no longer names (its node
    /// or the writer is gone) keeps its owner for a while: the samples it wrote before it
    /// left may still be waiting to be read (a babbler's last action, read after the
    /// babbler exited), and a GID is never reused, so no one else can claim it.
    pub fn update(
        &mut self,
        participant: Gid,
        nodes: impl IntoIterator<Item = (String, Vec<Gid>)>,
    ) {
        let named: HashMap<Gid, String> = nodes
            .into_iter()
            .flat_map(|(node, gids)| gids.into_iter().map(move |gid| (gid, node.clone())))
            .collect();
        for gone in self
            .writers_of_participant
            .remove(&participant)
            .unwrap_or_default()
        {
            if !named.contains_key(&gone) && self.announcer.get(&gone) == Some(&participant) {
                self.announcer.remove(&gone);
                self.departed.push_back(gone);
            }
        }
        while self.departed.len() > Self::DEPARTED_KEPT {
            self.forget_oldest_departed();
        }
        let mut kept = Vec::with_capacity(named.len());
        for (writer, node) in named {
            if !self.make_room_for(&writer) {
                self.refused += 1;
                continue;
            }
            self.node_of_writer.insert(writer, node);
            self.announcer.insert(writer, participant);
            kept.push(writer);
        }
        if !kept.is_empty() {
            self.writers_of_participant.insert(participant, kept);
        }
    }

    /// Whether `writer` has a place: it is known already, there is room, or a departed
    /// writer could be forgotten to make room.
    fn make_room_for(&mut self, writer: &Gid) -> bool {
        while !self.node_of_writer.contains_key(writer)
            && self.node_of_writer.len() >= Self::WRITERS_KEPT
        {
            if self.departed.is_empty() {
                return false;
            }
            self.forget_oldest_departed();
        }
        true
    }

    /// Forgets the oldest departed writer, unless a participant has named it again since.
    fn forget_oldest_departed(&mut self) {
        if let Some(writer) = self.departed.pop_front()
            && !self.announcer.contains_key(&writer)
            && !self.departed.contains(&writer)
        {
            self.node_of_writer.remove(&writer);
        }
    }

    /// The node that announced `writer`, if any has.
    pub fn node_of(&self, writer: &Gid) -> Option<&str> {
        self.node_of_writer.get(writer).map(String::as_str)
    }

    /// Writers known now (announced or departed recently).
    pub fn len(&self) -> usize {
        self.node_of_writer.len()
    }

    /// Whether no writer is known.
    pub fn is_empty(&self) -> bool {
        self.node_of_writer.is_empty()
    }

    /// Writers refused because the directory was full.
    pub fn refused(&self) -> u64 {
        self.refused
    }
}

/// The nodes a topic's samples are accepted from.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Trusted {
    /// Every writer (no identity check).
    Any,
    /// Writers these fully qualified nodes announced.
    Nodes(Vec<String>),
}

/// What a sample's writer is to a topic.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Origin {
    /// A trusted node's writer.
    Trusted,
    /// Another node's writer, by the name it announced.
    Foreign(String),
    /// A writer no participant has announced (yet).
    Unknown,
}

impl Trusted {
    /// `value` of a node's trust parameter: `*` trusts every writer; otherwise a
    /// comma-separated list of node names, each resolved against `namespace` unless
    /// absolute. `default` stands for an empty value.
    pub fn parse(value: &str, namespace: &str, default: &[&str]) -> Self {
        let names: Vec<&str> = match value.trim() {
            "*" => return Self::Any,
            "" => default.to_vec(),
            list => list
                .split(',')
                .map(str::trim)
                .filter(|n| !n.is_empty())
                .collect(),
        };
        let base = namespace.trim_end_matches('/');
        Self::Nodes(
            names
                .into_iter()
                .map(|n| match n.starts_with('/') {
                    true => n.to_owned(),
                    false => format!("{base}/{n}"),
                })
                .collect(),
        )
    }

    /// What `writer` is to this topic according to `directory`.
    pub fn judge(&self, directory: &WriterDirectory, writer: &Gid) -> Origin {
        let Self::Nodes(nodes) = self else {
            return Origin::Trusted;
        };
        match directory.node_of(writer) {
            Some(node) if nodes.iter().any(|n| n == node) => Origin::Trusted,
            Some(node) => Origin::Foreign(node.to_owned()),
            None => Origin::Unknown,
        }
    }
}

/// Counts of the samples a [`Quarantine`] kept out.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct QuarantineCounts {
    /// Samples of writers announced by an untrusted node.
    pub foreign: u64,
    /// Samples dropped unannounced because the quarantine was full.
    pub unidentified: u64,
}

/// Samples whose writer is not announced yet, held per writer until it is; bounded, so a
/// writer that never announces itself (a plain DDS program) costs a fixed amount of memory.
#[derive(Debug)]
pub struct Quarantine<T> {
    held: Vec<(Gid, VecDeque<T>)>,
    counts: QuarantineCounts,
}

impl<T> Default for Quarantine<T> {
    fn default() -> Self {
        Self {
            held: Vec::new(),
            counts: QuarantineCounts::default(),
        }
    }
}

impl<T> Quarantine<T> {
    /// Samples held per unannounced writer (a few seconds of a run): the oldest go first.
    pub const PER_WRITER: usize = 1024;
    /// Unannounced writers held at once: a new one beyond this is not held.
    pub const WRITERS: usize = 16;

    /// Admits `sample` from `writer` to a topic that trusts `trusted`: returns every sample
    /// now accepted, those released from quarantine first, in arrival order per writer.
    pub fn admit(
        &mut self,
        trusted: &Trusted,
        directory: &WriterDirectory,
        writer: Gid,
        sample: T,
    ) -> Vec<T> {
        let mut accepted = self.release(trusted, directory);
        match trusted.judge(directory, &writer) {
            Origin::Trusted => accepted.push(sample),
            Origin::Foreign(_) => self.counts.foreign += 1,
            Origin::Unknown => self.hold(writer, sample),
        }
        accepted
    }

    /// Releases the held samples of writers announced since: a trusted node's are
    /// returned, another node's are dropped and counted.
    pub fn release(&mut self, trusted: &Trusted, directory: &WriterDirectory) -> Vec<T> {
        let mut accepted = Vec::new();
        let mut index = 0;
        while index < self.held.len() {
            match trusted.judge(directory, &self.held[index].0) {
                Origin::Unknown => index += 1,
                Origin::Trusted => accepted.extend(self.held.remove(index).1),
                Origin::Foreign(_) => {
                    self.counts.foreign += self.held.remove(index).1.len() as u64;
                }
            }
        }
        accepted
    }

    fn hold(&mut self, writer: Gid, sample: T) {
        let queue = match self.held.iter().position(|(w, _)| *w == writer) {
            Some(i) => &mut self.held[i].1,
            None if self.held.len() < Self::WRITERS => {
                self.held.push((writer, VecDeque::new()));
                &mut self.held.last_mut().expect("just pushed").1
            }
            None => {
                self.counts.unidentified += 1;
                return;
            }
        };
        if queue.len() == Self::PER_WRITER {
            queue.pop_front();
            self.counts.unidentified += 1;
        }
        queue.push_back(sample);
    }

    /// Samples held now.
    pub fn held(&self) -> usize {
        self.held.iter().map(|(_, q)| q.len()).sum()
    }

    /// What was kept out so far.
    pub fn counts(&self) -> QuarantineCounts {
        self.counts
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const SIM: Gid = [1; 16];
    const STRAY: Gid = [2; 16];
    const IMPOSTOR: Gid = [3; 16];

    fn directory() -> WriterDirectory {
        let mut d = WriterDirectory::default();
        d.update([10; 16], [("/causal_arm_sim".to_owned(), vec![SIM])]);
        d.update([11; 16], [("/talker".to_owned(), vec![IMPOSTOR])]);
        d
    }

    #[test]
    fn trust_names_resolve_in_the_namespace_and_star_trusts_everyone() {
        let sim = ["causal_arm_sim"];
        assert_eq!(
            Trusted::parse("", "/run1", &sim),
            Trusted::Nodes(vec!["/run1/causal_arm_sim".into()])
        );
        assert_eq!(
            Trusted::parse("a, /b/c", "/", &sim),
            Trusted::Nodes(vec!["/a".into(), "/b/c".into()])
        );
        assert_eq!(Trusted::parse(" * ", "/", &sim), Trusted::Any);
        assert_eq!(
            Trusted::Any.judge(&WriterDirectory::default(), &STRAY),
            Origin::Trusted
        );
    }

    #[test]
    fn a_trusted_writer_passes_a_foreign_one_is_counted_an_unknown_one_waits() {
        let trusted = Trusted::parse("", "/", &["causal_arm_sim"]);
        let mut d = directory();
        let mut q = Quarantine::default();
        assert_eq!(q.admit(&trusted, &d, SIM, 1), vec![1]);
        assert_eq!(q.admit(&trusted, &d, IMPOSTOR, 2), Vec::<i32>::new());
        assert_eq!(q.admit(&trusted, &d, STRAY, 3), Vec::<i32>::new());
        assert_eq!((q.held(), q.counts().foreign), (1, 1));
        // A second simulator announces itself late: its held samples come out in order,
        // before the sample that follows them.
        let late: Gid = [4; 16];
        assert!(q.admit(&trusted, &d, late, 4).is_empty());
        assert!(q.admit(&trusted, &d, late, 5).is_empty());
        d.update([12; 16], [("/causal_arm_sim".to_owned(), vec![late])]);
        assert_eq!(q.admit(&trusted, &d, late, 6), vec![4, 5, 6]);
        // The stray announces itself as another node: its held sample is dropped.
        d.update([13; 16], [("/stray".to_owned(), vec![STRAY])]);
        assert!(q.release(&trusted, &d).is_empty());
        assert_eq!((q.held(), q.counts().foreign), (0, 2));
        // A participant's new announcement moves the writers it names.
        d.update([12; 16], [("/elsewhere".to_owned(), vec![late])]);
        assert_eq!(d.node_of(&SIM), Some("/causal_arm_sim"));
        assert_eq!(d.node_of(&late), Some("/elsewhere"));
    }

    #[test]
    fn a_departed_nodes_writer_keeps_its_owner_so_its_last_samples_pass() {
        // The babbler answers the last state and exits; its participant then announces no
        // nodes. The recorder reads the last action after that announcement.
        const BABBLER: Gid = [5; 16];
        let trusted = Trusted::parse("", "/", &["causal_arm_babbler"]);
        let mut d = WriterDirectory::default();
        d.update(
            [14; 16],
            [("/causal_arm_babbler".to_owned(), vec![BABBLER])],
        );
        d.update([14; 16], Vec::<(String, Vec<Gid>)>::new());
        let mut q = Quarantine::default();
        assert_eq!(q.admit(&trusted, &d, BABBLER, 7), vec![7]);
        assert_eq!(q.held(), 0);
    }

    fn gid(n: usize) -> Gid {
        let mut g = [0xee; 16];
        g[..8].copy_from_slice(&(n as u64).to_le_bytes());
        g
    }

    #[test]
    fn a_flood_of_fresh_writers_is_bounded_and_keeps_the_graphs_own() {
        let mut d = directory();
        // A hostile participant announces fresh writers without end, each announcement
        // replacing its last.
        let hostile: Gid = [20; 16];
        for round in 0..40 {
            let gids = (0..1000).map(|i| gid(round * 1000 + i)).collect();
            d.update(hostile, [("/flood".to_owned(), gids)]);
            assert!(d.len() <= WriterDirectory::WRITERS_KEPT, "{}", d.len());
        }
        assert_eq!(d.node_of(&SIM), Some("/causal_arm_sim"));
        assert_eq!(d.node_of(&IMPOSTOR), Some("/talker"));
        // The latest announcement stands; the oldest departures are forgotten.
        assert_eq!(d.node_of(&gid(39_999)), Some("/flood"));
        assert_eq!(d.node_of(&gid(0)), None);
        assert_eq!(d.refused(), 0);
        // Many participants each holding writers at once fill the directory: the
        // writers beyond it are refused, never the ones known already.
        for p in 0..40u8 {
            let gids = (0..1000)
                .map(|i| gid(100_000 + p as usize * 1000 + i))
                .collect();
            d.update([30 + p; 16], [("/crowd".to_owned(), gids)]);
        }
        assert_eq!(d.len(), WriterDirectory::WRITERS_KEPT);
        assert!(d.refused() > 0);
        assert_eq!(d.node_of(&SIM), Some("/causal_arm_sim"));
    }

    #[test]
    fn a_writer_named_again_is_not_forgotten_with_its_old_departure() {
        let mut d = WriterDirectory::default();
        let node = |gids: Vec<Gid>| [("/n".to_owned(), gids)];
        d.update([1; 16], node(vec![gid(1)]));
        d.update([1; 16], node(vec![]));
        d.update([1; 16], node(vec![gid(1)]));
        for i in 0..WriterDirectory::DEPARTED_KEPT + 1 {
            d.update([2; 16], node(vec![gid(10 + i)]));
        }
        assert_eq!(d.node_of(&gid(1)), Some("/n"));
        // Another participant taking a writer over: its first announcer leaving does
        // not make it depart.
        d.update([3; 16], node(vec![gid(1)]));
        d.update([1; 16], node(vec![]));
        for i in 0..WriterDirectory::DEPARTED_KEPT + 1 {
            d.update([2; 16], node(vec![gid(20_000 + i)]));
        }
        assert_eq!(d.node_of(&gid(1)), Some("/n"));
    }

    #[test]
    fn the_quarantine_is_bounded_per_writer_and_in_writers() {
        let trusted = Trusted::parse("", "/", &["causal_arm_sim"]);
        let d = WriterDirectory::default();
        let mut q = Quarantine::default();
        for i in 0..Quarantine::<usize>::PER_WRITER + 10 {
            q.admit(&trusted, &d, STRAY, i);
        }
        assert_eq!(q.held(), Quarantine::<usize>::PER_WRITER);
        assert_eq!(q.counts().unidentified, 10);
        for w in 0..Quarantine::<usize>::WRITERS as u8 + 5 {
            q.admit(&trusted, &d, [100 + w; 16], 0);
        }
        // The stray already held one slot: 16 writers in all, the other 6 not held.
        assert_eq!(q.counts().unidentified, 16);
        assert_eq!(
            q.held(),
            Quarantine::<usize>::PER_WRITER + Quarantine::<usize>::WRITERS - 1
        );
    }
}
