//! The step frames `watch` did not get live, fetched from the server's history: every frame of
//! a job carries its batch number `seq` (0, 1, 2, … per key), so a live frame whose `seq` is past
//! the next one expected shows a gap — frames put while a zenoh router between the server and
//! the watcher was down, dropped for a slow link, or dropped from `watch`'s own ring of unread
//! live samples while it was fetching — and the job's final status leaves the
//! frames after the last one seen. Both are asked of the history queryable
//! (`signorini/v1/jobs/{id}/{energy,state}/*?from_seq=N`, at most
//! [`stream::HISTORY_FRAMES`] replies per query, in no set order) and shown in `seq` order
//! before what comes next, so `watch --json` prints each frame once, in order, with no hole.

use crate::proto::v1 as pb;
use crate::stream;
use anyhow::{Result, anyhow};
use prost::Message;

/// The kinds of step frames, as in their keys.
pub(super) const KINDS: [&str; 2] = ["energy", "state"];

/// The next `seq` expected of each kind of frame (unknown until one is seen: a watcher that
/// comes late starts where it came in).
#[derive(Debug, Default)]
pub(super) struct Expected {
    next: [Option<u64>; 2],
}

impl Expected {
    /// What to show for the live frame `f` of kind `KINDS[k]`: the missing frames before it
    /// (from the history), then it; nothing when it was shown already.
    pub(super) async fn live(
        &mut self,
        session: &zenoh::Session,
        id: &str,
        k: usize,
        f: pb::StepFrame,
    ) -> Result<Vec<pb::StepFrame>> {
        let mut shown = Vec::new();
        match self.next[k] {
            Some(next) if f.seq < next => return Ok(shown),
            Some(next) if f.seq > next => {
                shown = fetch(session, id, KINDS[k], next, Some(f.seq)).await?;
            }
            _ => {}
        }
        self.next[k] = Some(f.seq + 1);
        shown.push(f);
        Ok(shown)
    }

    /// The frames of kind `KINDS[k]` after the last one shown, to the job's last (once it has
    /// ended): nothing for a kind never seen live.
    pub(super) async fn rest(
        &mut self,
        session: &zenoh::Session,
        id: &str,
        k: usize,
    ) -> Result<Vec<pb::StepFrame>> {
        let Some(next) = self.next[k] else {
            return Ok(Vec::new());
        };
        let mut rest = fetch(session, id, KINDS[k], next, None).await?;
        if let Some(last) = rest.last_mut() {
            self.next[k] = Some(last.seq + 1);
            // Asked once the job's status is terminal, so the history ends with the job's last
            // frame; the history marks it `last` only once it has seen the job end itself,
            // which may come after the status the watcher acted on.
            last.last = true;
        }
        Ok(rest)
    }
}

/// How long one history query may take: the server reads up to [`stream::HISTORY_FRAMES`]
/// frames from its store for it, on a machine that may be busy with the jobs themselves.
const HISTORY_TIMEOUT: std::time::Duration = std::time::Duration::from_secs(15);

/// Times a history query is asked before its timeout is an error: a query the server drops
/// without a final reply (zenoh 1.10.2 did, for a query naming a key-expression resource the
/// watcher was undeclaring: `watch_session` now keeps its subscription until the history
/// queries end) is asked again; the query is idempotent.
const HISTORY_ATTEMPTS: usize = 3;

/// The recorded frames of `kind` with `from ≤ seq < before` (to the last one when `before` is
/// `None`), in `seq` order, asked [`stream::HISTORY_FRAMES`] at a time.
async fn fetch(
    session: &zenoh::Session,
    id: &str,
    kind: &str,
    from: u64,
    before: Option<u64>,
) -> Result<Vec<pb::StepFrame>> {
    let key = match kind {
        "energy" => stream::energy_key(id),
        _ => stream::state_key(id),
    };
    let mut frames: Vec<pb::StepFrame> = Vec::new();
    let mut from = from;
    loop {
        let selector = format!("{key}/*?from_seq={from}");
        let mut attempt = 1;
        let mut got = loop {
            match ask(session, &selector).await? {
                Answer::Frames(got) => break got,
                Answer::TimedOut if attempt < HISTORY_ATTEMPTS => {
                    tracing::warn!("history query {selector} timed out; asking again");
                    attempt += 1;
                }
                Answer::TimedOut => {
                    return Err(anyhow!(
                        "history of {key}: no answer in {HISTORY_ATTEMPTS} queries of {} s each",
                        HISTORY_TIMEOUT.as_secs()
                    ));
                }
            }
        };
        got.sort_by_key(|f| f.seq);
        got.dedup_by_key(|f| f.seq);
        let full = got.len() >= stream::HISTORY_FRAMES;
        let Some(last) = got.last().map(|f| f.seq) else {
            return Ok(frames);
        };
        frames.extend(
            got.into_iter()
                .filter(|f| f.seq >= from && before.is_none_or(|b| f.seq < b)),
        );
        let done = before.is_some_and(|b| last + 1 >= b) || frames.last().is_some_and(|f| f.last);
        if done || !full {
            return Ok(frames);
        }
        from = last + 1;
    }
}

/// What one history query gave.
enum Answer {
    /// Its frames (all of them: the query ended).
    Frames(Vec<pb::StepFrame>),
    /// The query's timeout passed before it ended.
    TimedOut,
}

/// One history query of `selector`: its frames, or that it timed out; an error reply (an
/// unknown job) or an undecodable frame is an error.
async fn ask(session: &zenoh::Session, selector: &str) -> Result<Answer> {
    let replies = session
        .get(selector)
        .timeout(HISTORY_TIMEOUT)
        .await
        .map_err(|e| anyhow!("zenoh get of the history: {e}"))?;
    let mut got = Vec::new();
    while let Ok(reply) = replies.recv_async().await {
        match reply.result() {
            Ok(sample) => got.push(pb::StepFrame::decode(&*sample.payload().to_bytes())?),
            Err(e) => {
                let why = String::from_utf8_lossy(&e.payload().to_bytes()).into_owned();
                if why == "Timeout" {
                    return Ok(Answer::TimedOut);
                }
                return Err(anyhow!("history of {selector}: {why}"));
            }
        }
    }
    Ok(Answer::Frames(got))
}
