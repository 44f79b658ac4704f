//! Alg. 3's constrained collapse replayed against the dated one it shadows.
//!
//! Alg. 2 keeping W removes almost exactly the pairs of the unconstrained collapse: a face
//! of W outlives its date, and the faces around it may then pair differently, but nothing
//! else changes (classroom box 430: 10 492 of 133.6 M faces die at another layer; door:
//! 745 of 14.2 M). Both collapses are local: whether a face goes in a layer depends only on
//! the states, at the layer's start, of the cells within [`REACH`] of it. So the
//! constrained run is simulated explicitly only in a zone around the faces where the two
//! runs differ (and around each face of W from the layer the unconstrained run removes
//! it); outside the zone its state at layer t is read off the dates (a face is alive iff
//! it dies at t or later), and its pairs are those of the unconstrained run.
//!
//! The zone grows by a ball of radius [`REACH`] around every face whose state comes to
//! differ, so at each layer's start it holds every face within reach of a difference, and
//! every face outside it does what the dated run did. Inside, the faces' state bytes are
//! kept as in [`collapse_from`](super::collapse_from), with coface counts updated when a
//! coface outside the zone dies at its date.

use super::{is_free, Dates, KeptFaces, Neighbours, Pair, ALIVE, COUNT, NEVER, TYPE_SHIFT};
use crate::complex::Complex;
use crate::grid::{BitSet, SparseBytes};

/// L1 radius, in the doubled grid, of the cells whose states decide whether a face goes in
/// a layer. As the smaller face g of a pair: g's cofaces (1 step), that coface's facets
/// (2) and, for their counts, their cofaces (3). As the larger face f: f is maximal (its
/// cofaces, 1) and has a free facet (2).
const REACH: i64 = 3;

/// Above this share of the complex's faces in the zone the explicit simulation stops
/// paying for itself; the caller then runs the dense collapse.
const MAX_ZONE_SHARE: usize = 16;

/// Moves `x` (the complex `dates` were taken on) to the end of Alg. 2 keeping the faces of
/// `keep` (a closed set), as [`collapse_from`](super::collapse_from) from `x` would.
/// Returns the faces left in increasing order, or `None`, leaving `x` as it was, if the two
/// collapses differ too widely for the replay to be worth it.
pub(super) fn replay_constrained(x: &mut Complex, dates: &Dates, keep: &KeptFaces) -> Option<Vec<usize>> {
    let most = x.cells.len() / MAX_ZONE_SHARE;
    replay_within(x, dates, keep, most)
}

/// [`replay_constrained`] giving up once the zone holds more than `most` faces.
pub(super) fn replay_within(x: &mut Complex, dates: &Dates, keep: &KeptFaces, most: usize) -> Option<Vec<usize>> {
    let zone = Replay::new(x, dates, keep).run(most)?;
    // The faces the dated run leaves, then the zone's as the constrained run leaves them.
    let mut faces = dates.keep_survivors(&mut x.cells);
    for &(i, alive) in &zone {
        x.cells[i] = alive;
    }
    faces.extend(zone.iter().filter(|&&(_, alive)| alive).map(|&(i, _)| i));
    faces.sort_unstable();
    faces.dedup();
    faces.retain(|&i| x.cells[i]);
    Some(faces)
}

/// The constrained collapse inside the zone.
struct Replay<'a> {
    x: &'a Complex,
    dates: &'a Dates,
    keep: &'a KeptFaces,
    steps: Neighbours,
    /// Cell offsets within [`REACH`], as coordinate steps.
    ball: Vec<[i64; 3]>,
    zone: BitSet,
    /// Faces whose ball is in the zone already.
    grown: BitSet,
    /// Every zone face, in the order it joined.
    members: Vec<usize>,
    /// State bytes of the zone's faces (see [`COUNT`](super::COUNT)); 0 elsewhere.
    state: SparseBytes,
    /// Zone faces by their death date: where the two runs may part if it is not kept.
    dies: Vec<Vec<usize>>,
    /// (zone face, coface outside the zone when it joined) by the coface's death date: the
    /// face loses that coface then, unless the coface has joined the zone since.
    loses: Vec<Vec<(usize, usize)>>,
    /// Faces of W by death date (those the dated run removes).
    kept_dying: Vec<Vec<usize>>,
}

impl<'a> Replay<'a> {
    fn new(x: &'a Complex, dates: &'a Dates, keep: &'a KeptFaces) -> Replay<'a> {
        let n = x.cells.len();
        let last = usize::from(dates.last);
        let mut kept_dying = vec![Vec::new(); last + 2];
        for &i in keep.faces().iter().filter(|&&i| dates.death(i) != NEVER) {
            kept_dying[dates.death(i) as usize].push(i);
        }
        let r = REACH;
        let mut ball = Vec::new();
        for dz in -r..=r {
            for dy in -r..=r {
                for dx in -r..=r {
                    if dx.abs() + dy.abs() + dz.abs() <= r {
                        ball.push([dx, dy, dz]);
                    }
                }
            }
        }
        Replay {
            x,
            dates,
            keep,
            steps: Neighbours::new(x),
            ball,
            zone: BitSet::new(n),
            grown: BitSet::new(n),
            members: Vec::new(),
            state: SparseBytes::new(n),
            dies: vec![Vec::new(); last + 2],
            loses: vec![Vec::new(); last + 2],
            kept_dying,
        }
    }

    /// Whether face `i` is alive at the start of layer `t` in the dated run.
    fn dated_alive(&self, i: usize, t: u32) -> bool {
        self.x.cells[i] && u32::from(self.dates.death(i)) >= t
    }

    /// Whether face `i` is alive at the start of layer `t` of the constrained run (the
    /// zone's states being those of layer `t`).
    fn alive_at(&self, i: usize, t: u32) -> bool {
        if self.zone.contains(i) {
            self.state[i] & ALIVE != 0
        } else {
            self.dated_alive(i, t)
        }
    }

    /// The state byte of face `i`, alive and of type `ty`, with its cofaces alive at the
    /// start of layer `t` (as [`Replay::alive_at`]).
    fn alive_state_at(&self, i: usize, ty: u8, t: u32) -> u8 {
        self.steps.state_of(i, ty, self.keep.contains(i), |c| self.alive_at(c, t))
    }

    /// The state byte of face `i` at the start of layer `t` of the constrained run.
    fn state_at(&self, i: usize, t: u32) -> u8 {
        if self.zone.contains(i) {
            return self.state[i];
        }
        // Outside the zone the face is as in the dated run.
        if !self.dated_alive(i, t) {
            return 0;
        }
        self.alive_state_at(i, self.x.face_type(i), t)
    }

    /// Adds the cells within [`REACH`] of each of `seeds` to the zone, with their states at
    /// the start of layer `t`; the new faces free then go to `free`.
    fn grow(&mut self, seeds: &[usize], t: u32, free: &mut Vec<usize>) {
        let dims = self.x.dims.map(|d| d as i64);
        let first = self.members.len();
        for &s in seeds {
            if !self.grown.insert(s) {
                continue;
            }
            let p = self.x.coords(s).map(|c| c as i64);
            for d in &self.ball {
                let q = [p[0] + d[0], p[1] + d[1], p[2] + d[2]];
                if (0..3).any(|a| q[a] < 0 || q[a] >= dims[a]) {
                    continue;
                }
                let j = self.x.index(q.map(|c| c as usize));
                if self.x.cells[j] && self.zone.insert(j) {
                    self.members.push(j);
                }
            }
        }
        // The new faces were outside the zone until now, so as in the dated run.
        for k in first..self.members.len() {
            let j = self.members[k];
            let alive = self.dated_alive(j, t);
            self.state[j] = (u8::from(alive) * ALIVE) | (self.x.face_type(j) << TYPE_SHIFT);
        }
        for k in first..self.members.len() {
            let j = self.members[k];
            if self.state[j] & ALIVE == 0 {
                continue;
            }
            self.state[j] = self.alive_state_at(j, self.state[j] >> TYPE_SHIFT, t);
            // Cofaces outside the zone die at their dates; j is told then.
            for &o in self.steps.cofaces(self.state[j]) {
                let c = j.wrapping_add_signed(o);
                let death = self.dates.death(c);
                if !self.zone.contains(c) && self.dated_alive(c, t) && death != NEVER {
                    self.loses[death as usize].push((j, c));
                }
            }
            let death = self.dates.death(j);
            if death != NEVER {
                self.dies[death as usize].push(j);
            }
            if is_free(self.state[j]) {
                free.push(j);
            }
        }
    }

    /// Takes a zone face out of the complex; facets in the zone left free go to `free`.
    fn remove(&mut self, face: usize, free: &mut Vec<usize>) {
        self.state[face] &= !ALIVE;
        // A copy, as the loop changes the zone's states.
        let facets = self.steps.facets[(self.state[face] >> TYPE_SHIFT) as usize];
        for &o in facets.as_slice() {
            self.lose_coface(face.wrapping_add_signed(o), free);
        }
    }

    /// Zone face `h` lost a coface.
    fn lose_coface(&mut self, h: usize, free: &mut Vec<usize>) {
        if self.zone.contains(h) {
            self.state[h] -= 1;
            if is_free(self.state[h]) {
                free.push(h);
            }
        }
    }

    /// Runs the constrained collapse to its end; the zone's faces and whether each is left,
    /// or `None` if the zone outgrew `most` faces.
    fn run(mut self, most: usize) -> Option<Vec<(usize, bool)>> {
        let Some(start) = self.kept_dying.iter().position(|k| !k.is_empty()) else {
            return Some(Vec::new()); // the dated run removes no face of W: nothing differs
        };
        let last = self.dies.len() - 2;
        let mut free = Vec::new();
        let sources = std::mem::take(&mut self.kept_dying[start]);
        self.grow(&sources, start as u32, &mut free);
        let mut t = start as u32;
        let mut pairs: Vec<Pair> = Vec::new();
        let mut parted = Vec::new();
        while !free.is_empty() || t as usize <= last {
            let layer = t as usize;
            // The layer's pairs in the zone, from the states at its start.
            pairs.clear();
            for &g in &free {
                pairs.extend(self.steps.layer_pair(|i| self.state_at(i, t), g).map(|(f, _, _)| (f, g)));
            }
            // A face the dated run removes now may lose its free facet outside the zone,
            // where no coface count is followed: the only such facets are of faces the
            // dated run removes in this layer (a free facet's coface goes in its layer).
            let dying = std::mem::take(&mut self.dies[layer.min(last + 1)]);
            for &f in &dying {
                let s = self.state[f];
                if s & (ALIVE | COUNT) != ALIVE {
                    continue; // gone already, kept, or not maximal
                }
                let first_free = self.steps.first_free_facet(&|i| self.state_at(i, t), f).map(|(_, h)| h);
                if let Some(h) = first_free.filter(|&h| !self.zone.contains(h)) {
                    pairs.push((f, h));
                }
            }
            pairs.sort_unstable();
            pairs.dedup();
            free.clear();
            // Remove them; faces outside the zone go as in the dated run, at this layer.
            parted.clear();
            for &(f, g) in &pairs {
                for face in [f, g] {
                    if self.zone.contains(face) {
                        self.remove(face, &mut free);
                        if u32::from(self.dates.death(face)) != t {
                            parted.push(face);
                        }
                    }
                }
            }
            if layer <= last {
                for (h, c) in std::mem::take(&mut self.loses[layer]) {
                    if !self.zone.contains(c) {
                        self.lose_coface(h, &mut free);
                    }
                }
            }
            // Faces the dated run removed now and this one kept.
            parted.extend(dying.into_iter().filter(|&f| self.state[f] & ALIVE != 0));
            if layer < last {
                parted.extend(std::mem::take(&mut self.kept_dying[layer + 1]));
            }
            self.grow(&parted, t + 1, &mut free);
            if self.members.len() > most {
                return None;
            }
            t += 1;
        }
        Some(self.members.iter().map(|&i| (i, self.state[i] & ALIVE != 0)).collect())
    }
}
