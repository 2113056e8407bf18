//! Which finished segments of a run a resumed forward stage can continue from, and setting
//! aside the rest.
//!
//! A killed run leaves at most one unfinished segment, which is discarded; a damaged disk or
//! a hand that moved files can leave damaged, missing or misnamed segments anywhere, and
//! everything from the first of them on is recomputed (the dynamics is deterministic, so
//! bit for bit).
//! Nothing readable is deleted before its replacement is written: damaged segments are kept
//! as `.corrupt`, the intact ones after them as `.superseded` until the stage has rewritten
//! them.

use super::records::{Checkpoint, Stats};
use super::run::{RunDir, SegmentFile};
use super::schema::{CHECKPOINT, STATS};
use super::segment::{read_segment, ReadMode, RUN_METADATA};
use crate::error::{Error, Result};
use std::path::{Path, PathBuf};

/// Remove the segments a killed run left unfinished (`.tmp`), saying what each held: the
/// run continues from a finished segment's checkpoint, and recomputes what they held.
pub fn discard_partial_segments(dir: &RunDir, notice: &mut dyn FnMut(String)) -> Result<()> {
    for partial in dir.partial_segments()? {
        let mut checkpoints = 0u64;
        let mut last = None;
        let report = read_segment(&partial, ReadMode::Salvage, |m| {
            if m.topic == CHECKPOINT.topic {
                checkpoints += 1;
                last = Some(m.step);
            }
            Ok(())
        });
        let what = match (report, last) {
            (Ok(_), Some(step)) => format!("{checkpoints} complete checkpoints up to step {step}"),
            _ => "no complete checkpoint".to_string(),
        };
        notice(format!("discarding the interrupted segment {} ({what}); they will be recomputed", partial.display()));
        std::fs::remove_file(&partial).map_err(|e| Error::io(&partial, e))?;
    }
    Ok(())
}

/// What a resume keeps of the finished segments.
pub struct Triage {
    /// The last checkpoint of the newest segment before any damage: the run continues
    /// from it.
    pub newest_intact: Option<LastCheckpoint>,
    /// Intact segments after the damage, set aside until their replacements are written.
    pub superseded: Vec<PathBuf>,
}

/// Read every finished segment whole (CRCs checked). From the oldest damaged one on, the
/// segments are recomputed from the last intact checkpoint before it: the dynamics is
/// deterministic, so the new files hold the numbers of the old, bit for bit (only wall
/// times differ). Damaged segments are moved aside as `.corrupt`, the intact ones after
/// them as `.superseded`, together with any a repair that was itself interrupted left.
///
/// A segment missing between two others (moved out, deleted) is a gap in the checkpoints,
/// which the backward stage would stop at: the segments after it are recomputed the same way.
///
/// So are the checkpoints missing before the first segment, where the backward stage needs
/// them (from `needed_from`, the first step of its work, on): there is no checkpoint before
/// them, and the run is recomputed from step 0. Segments before that step are pruned by
/// design.
///
/// A segment whose steps are not those its name says ([`SegmentFile::misnamed`]: renamed,
/// or copied in under another name) is moved aside as `.corrupt` first, and only the gap it
/// may leave is recomputed: a stray copy costs nothing, two swapped names the steps from the
/// first of them on.
pub fn triage(dir: &RunDir, checkpoint_every: u64, needed_from: u64, notice: &mut dyn FnMut(String)) -> Result<Triage> {
    let all = dir.segments()?;
    let mut reads: Vec<Result<()>> = Vec::with_capacity(all.len());
    let mut misnamed = vec![false; all.len()];
    // The newest segment read before the first damaged one, with its last checkpoint: the
    // one the run continues from unless a gap comes earlier.
    let mut newest_read: Option<(PathBuf, LastCheckpoint)> = None;
    let mut damage_seen = false;
    for (i, seg) in all.iter().enumerate() {
        match read_last(&seg.path) {
            // A file that cannot be read (permissions, a failing disk) is not damaged:
            // recomputing it and everything after it would cost hours for nothing.
            Err(e @ Error::Io { .. }) => {
                return Err(Error::Other(format!("{e}; nothing was changed: make the file readable (its permissions, the disk) and resume again")));
            }
            Ok((held, last)) => match seg.misnamed(Some(held)) {
                Some(why) => {
                    misnamed[i] = true;
                    reads.push(Err(Error::Other(why)));
                }
                None => {
                    if !damage_seen {
                        newest_read = Some((seg.path.clone(), last));
                    }
                    reads.push(Ok(()));
                }
            },
            Err(e) => {
                damage_seen = true;
                reads.push(Err(e));
            }
        }
    }
    // Misnamed segments are set aside now; the gaps they leave are found below.
    let (mut segments, mut kept): (Vec<SegmentFile>, Vec<Result<()>>) = (Vec::with_capacity(all.len()), Vec::with_capacity(all.len()));
    for ((seg, read), m) in all.into_iter().zip(reads).zip(misnamed) {
        match read {
            Err(e) if m => {
                let aside = corrupt_aside(&seg.path);
                notice(format!("{e}; moving it aside to {} (the steps it holds are recomputed where no other segment holds them)", aside.display()));
                std::fs::rename(&seg.path, &aside).map_err(|e| Error::io(&seg.path, e))?;
            }
            read => {
                segments.push(seg);
                kept.push(read);
            }
        }
    }
    let reads = kept;
    let damaged = reads.iter().position(Result::is_err).unwrap_or(segments.len());
    let c = checkpoint_every.max(1);
    // A segment begins at the checkpoint after the last one of the segment before, or
    // earlier: at the checkpoint of its own that a stop on a signal wrote (off the grid of
    // every C steps) before the next one was due.
    let gap = segments.windows(2).position(|w| !(w[0].last < w[1].first && w[1].first <= (w[0].last / c + 1) * c)).map(|i| i + 1);
    // The checkpoint the backward stage starts its recomputation from, at the latest.
    let needed = needed_from / c * c;
    let leading = segments.first().filter(|s| s.first > needed).map(|s| s.first);
    if let Some(first) = leading {
        notice(format!("the checkpoints of steps {needed}..{} are missing (no segment holds them), and the backward stage needs them: recomputing the run from step 0", first - 1));
    } else if let Some(i) = gap.filter(|&i| i < damaged) {
        notice(format!("the checkpoints of steps {}..{} are missing (no segment holds them): recomputing them and what follows", (segments[i - 1].last / c + 1) * c, segments[i].first - 1));
    }
    let intact = if leading.is_some() { 0 } else { gap.map_or(damaged, |g| g.min(damaged)) };
    let cause = if intact < damaged { "the missing checkpoints" } else { "a damaged segment" };
    let mut superseded: Vec<PathBuf> = std::fs::read_dir(&dir.path)
        .map_err(|e| Error::io(&dir.path, e))?
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.to_string_lossy().ends_with(".mcap.superseded"))
        .collect();
    for (seg, read) in segments[intact..].iter().zip(&reads[intact..]) {
        let aside = match read {
            Err(e) => {
                let aside = corrupt_aside(&seg.path);
                notice(format!("{e}; moving it aside to {} and recomputing from the checkpoint before it", aside.display()));
                aside
            }
            Ok(()) => {
                let aside = seg.path.with_extension("mcap.superseded");
                notice(format!("{} follows {cause} and is recomputed with {} (kept as {} until then)", seg.path.display(), if intact < damaged { "them" } else { "it" }, aside.display()));
                superseded.push(aside.clone());
                aside
            }
        };
        std::fs::rename(&seg.path, &aside).map_err(|e| Error::io(&seg.path, e))?;
    }
    let newest_intact = match (intact.checked_sub(1), newest_read) {
        (None, _) => None,
        (Some(i), Some((read, last))) if read == segments[i].path => Some(last),
        (Some(i), _) => Some(read_last(&segments[i].path)?.1),
    };
    Ok(Triage { newest_intact, superseded })
}

/// What the newest intact segment says about where the run stands.
pub struct LastCheckpoint {
    pub checkpoint: Checkpoint,
    pub stats: Stats,
}

/// Where a damaged segment is kept: FILE.corrupt, or FILE.2.corrupt, ... where an earlier
/// damaged segment of the same name is kept already (a second damage must not replace it).
fn corrupt_aside(path: &Path) -> PathBuf {
    let mut aside = path.with_extension("mcap.corrupt");
    let mut i = 1;
    while aside.symlink_metadata().is_ok() {
        i += 1;
        aside = path.with_extension(format!("{i}.mcap.corrupt"));
    }
    aside
}

/// The last checkpoint and stats of a finished segment, reading it whole (CRCs checked),
/// with the steps the writer named it by: those of its first message and its last checkpoint.
fn read_last(path: &Path) -> Result<((u64, u64), LastCheckpoint)> {
    let (mut first, mut cp, mut stats) = (None, None, None);
    read_segment(path, ReadMode::Strict, |m| {
        let bad = |e: String| Error::corrupt(path, format!("step {}: {e}", m.step));
        if m.topic != RUN_METADATA {
            first.get_or_insert(m.step);
        }
        if m.topic == CHECKPOINT.topic {
            cp = Some((m.step, Checkpoint::decode(m.data).map_err(bad)?));
        } else if m.topic == STATS.topic {
            stats = Some(Stats::decode(m.data).map_err(bad)?);
        }
        Ok(())
    })?;
    match (first, cp, stats) {
        (Some(first), Some((last, checkpoint)), Some(stats)) if stats.step == checkpoint.state.step => Ok(((first, last), LastCheckpoint { checkpoint, stats })),
        _ => Err(Error::corrupt(path, "no complete checkpoint with its statistics")),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A second damaged segment of one name is kept beside the first, not over it.
    #[test]
    fn damaged_segments_of_one_name_are_all_kept() {
        let dir = std::env::temp_dir().join(format!("clv-corrupt-aside-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let seg = dir.join("seg-000000000000-000000000100.mcap");
        assert_eq!(corrupt_aside(&seg), dir.join("seg-000000000000-000000000100.mcap.corrupt"));
        std::fs::write(dir.join("seg-000000000000-000000000100.mcap.corrupt"), b"first").unwrap();
        assert_eq!(corrupt_aside(&seg), dir.join("seg-000000000000-000000000100.2.mcap.corrupt"));
        std::fs::write(dir.join("seg-000000000000-000000000100.2.mcap.corrupt"), b"second").unwrap();
        assert_eq!(corrupt_aside(&seg), dir.join("seg-000000000000-000000000100.3.mcap.corrupt"));
        let _ = std::fs::remove_dir_all(&dir);
    }
}
