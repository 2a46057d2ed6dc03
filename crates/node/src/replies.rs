//! Replies that wait for their client without stalling the node's other clients.
//!
//! A client's first request can arrive before the server has matched the client's reply
//! reader; a reply written then reaches no one. ros2-client's `send_response` waits for
//! the match, but it blocks: a service node answers every client from one loop, so one
//! client whose reply reader never appears (a stray or hostile program) would hold every
//! other client up for the whole wait, on each of its requests. [`Replies`] instead holds
//! such a reply and sends it from a later turn of the loop, once the reader is matched or
//! the wait is over, while the loop goes on answering.

use std::cell::RefCell;
use std::time::{Duration, Instant};

use ros2_client::service::{REPLY_READER_WAIT, Server};
use ros2_client::{Message, RmwRequestId};

use crate::run::Served;

/// What to do with a reply now.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ReplyDue {
    /// Send it: the client's reply reader is matched (or matches are not tracked).
    Send,
    /// Send it although no reply reader of the client matched: the wait is over.
    SendUnmatched,
    /// Keep it: the client's reply reader may still be matched.
    Hold,
}

impl ReplyDue {
    /// The decision for a reply whose client reader is `matched` (`None`: not tracked)
    /// at `now`, held until `deadline`.
    pub fn decide(matched: Option<bool>, now: Instant, deadline: Instant) -> Self {
        match matched {
            None | Some(true) => Self::Send,
            Some(false) if now >= deadline => Self::SendUnmatched,
            Some(false) => Self::Hold,
        }
    }
}

/// A reply held for its client's reader, whatever the service's types.
trait HeldReply {
    fn matched(&self) -> Option<bool>;
    fn deadline(&self) -> Instant;
    /// Sends the reply; whether it went out.
    fn send(self: Box<Self>) -> bool;
}

struct Held<'a, Req: Message, Resp: Message> {
    server: &'a Server<Req, Resp>,
    id: RmwRequestId,
    response: Resp,
    deadline: Instant,
}

impl<Req: Message + 'static, Resp: Message + 'static> HeldReply for Held<'_, Req, Resp> {
    fn matched(&self) -> Option<bool> {
        self.server.reply_reader_matched(&self.id)
    }
    fn deadline(&self) -> Instant {
        self.deadline
    }
    fn send(self: Box<Self>) -> bool {
        self.server
            .send_response_now(self.id, self.response)
            .is_ok()
    }
}

/// The replies of one service loop that wait for their clients' reply readers.
pub struct Replies<'a> {
    held: RefCell<Vec<Box<dyn HeldReply + 'a>>>,
    wait: Duration,
    /// Replies sent without a matched reader of their client (logged only at first: a
    /// stray program flooding the node would fill the log).
    unmatched: std::cell::Cell<u64>,
}

impl Default for Replies<'_> {
    fn default() -> Self {
        Self::new(REPLY_READER_WAIT)
    }
}

impl<'a> Replies<'a> {
    /// Replies held at once; beyond this a reply goes out at once, matched or not, so a
    /// flood of requests from readerless clients costs bounded memory.
    pub const MAX_HELD: usize = 64;
    /// How often held replies look for their client's reader again.
    pub const RECHECK: Duration = Duration::from_millis(2);
    /// Replies sent unmatched that are logged one by one before they are only counted.
    const LOGGED: u64 = 5;

    /// Replies held up to `wait` each.
    pub fn new(wait: Duration) -> Self {
        Self {
            held: RefCell::new(Vec::new()),
            wait,
            unmatched: std::cell::Cell::new(0),
        }
    }

    /// Answers what `server.async_receive_request()` gave with `handle`'s response (see
    /// [`Replies::answer`]), or says the request could not be read.
    pub fn reply<Req, Resp, E>(
        &self,
        server: &'a Server<Req, Resp>,
        received: Result<(RmwRequestId, Req), E>,
        handle: impl FnOnce(&Req) -> Resp,
    ) -> Served
    where
        Req: Message + 'static,
        Resp: Message + 'static,
    {
        match received {
            Ok((id, request)) => self.answer(server, id, handle(&request)),
            Err(_) => Served::Unreadable,
        }
    }

    /// Answers the request `id` of `server` with `response`: now if the client's reply
    /// reader is matched, else later (see [`Replies::resend_due`]).
    pub fn answer<Req, Resp>(
        &self,
        server: &'a Server<Req, Resp>,
        id: RmwRequestId,
        response: Resp,
    ) -> Served
    where
        Req: Message + 'static,
        Resp: Message + 'static,
    {
        let now = Instant::now();
        let deadline = now + self.wait;
        let mut list = self.held.borrow_mut();
        match ReplyDue::decide(server.reply_reader_matched(&id), now, deadline) {
            ReplyDue::Hold if list.len() < Self::MAX_HELD => {
                list.push(Box::new(Held {
                    server,
                    id,
                    response,
                    deadline,
                }));
                Served::Held
            }
            ReplyDue::Hold => {
                self.count_unmatched(format_args!(
                    "{} replies already wait for their clients' reply readers; sent one at once",
                    Self::MAX_HELD
                ));
                sent(server.send_response_now(id, response).is_ok())
            }
            ReplyDue::Send | ReplyDue::SendUnmatched => {
                sent(server.send_response_now(id, response).is_ok())
            }
        }
    }

    /// Replies held now.
    pub fn held(&self) -> usize {
        self.held.borrow().len()
    }

    /// Waits [`Replies::RECHECK`] (for ever while none is held), then sends every held
    /// reply that is due: a future for the service loop's `select!`.
    pub async fn resend_due(&self) -> Served {
        if self.held() == 0 {
            std::future::pending::<()>().await;
        }
        tokio::time::sleep(Self::RECHECK).await;
        self.send_due(Instant::now())
    }

    /// Sends every held reply now, matched or not, and logs how many replies went out
    /// unmatched: for a loop that is stopping.
    pub fn finish(&self) -> Served {
        let served = self.send_due(Instant::now() + self.wait);
        if self.unmatched() > 0 {
            tracing::info!(
                "{} replies went out before their client's reply reader matched",
                self.unmatched()
            );
        }
        served
    }

    fn send_due(&self, now: Instant) -> Served {
        let mut list = self.held.borrow_mut();
        let mut all_sent = true;
        let mut index = 0;
        while index < list.len() {
            let due = ReplyDue::decide(list[index].matched(), now, list[index].deadline());
            if due == ReplyDue::Hold {
                index += 1;
                continue;
            }
            if due == ReplyDue::SendUnmatched {
                self.count_unmatched(format_args!(
                    "no reply reader of a client matched within {:?}; sent its reply anyway",
                    self.wait
                ));
            }
            all_sent &= list.remove(index).send();
        }
        sent(all_sent)
    }

    /// Replies sent so far without a matched reader of their client.
    pub fn unmatched(&self) -> u64 {
        self.unmatched.get()
    }

    fn count_unmatched(&self, what: std::fmt::Arguments<'_>) {
        let n = self.unmatched.get() + 1;
        self.unmatched.set(n);
        if n <= Self::LOGGED {
            tracing::warn!("{what} ({n} so far; logged up to {})", Self::LOGGED);
        }
    }
}

fn sent(ok: bool) -> Served {
    match ok {
        true => Served::Replied,
        false => Served::ReplyNotSent,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_matched_or_untracked_reader_gets_its_reply_at_once() {
        let now = Instant::now();
        let later = now + Duration::from_secs(1);
        assert_eq!(ReplyDue::decide(Some(true), now, later), ReplyDue::Send);
        assert_eq!(ReplyDue::decide(None, now, later), ReplyDue::Send);
    }

    #[test]
    fn an_unmatched_reply_waits_until_its_deadline_then_goes_anyway() {
        let now = Instant::now();
        let deadline = now + Duration::from_secs(1);
        assert_eq!(ReplyDue::decide(Some(false), now, deadline), ReplyDue::Hold);
        assert_eq!(
            ReplyDue::decide(Some(false), deadline, deadline),
            ReplyDue::SendUnmatched
        );
        assert_eq!(
            ReplyDue::decide(Some(false), deadline + Duration::from_millis(1), deadline),
            ReplyDue::SendUnmatched
        );
    }
}
