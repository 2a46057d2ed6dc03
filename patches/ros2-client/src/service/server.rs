#[cfg(any(feature = "mio_06", feature = "mio_1"))]
use std::io;
use std::{
  collections::{BTreeMap, BTreeSet},
  sync::{Arc, Mutex},
  time::{Duration, Instant},
};

#[cfg(feature = "mio_06")]
use rustdds::mio::{Evented, Poll, PollOpt, Ready, Token};
#[cfg(feature = "mio_1")]
use rustdds::mio1;
use rustdds::{rpc::*, *};
#[allow(unused_imports)]
use log::{debug, error, info, warn};
use futures::{StreamExt, pin_mut, stream::FusedStream};

use crate::{
  error::{CreateResult, ReadError, ReadResult, WriteError, WriteResult},
  message::Message,
  message_info::MessageInfo,
  node::Node,
  qos::QosProfile,
  service::*,
};

// --------------------------------------------
// --------------------------------------------
/// Server end of a ROS2 Service
pub struct Server<Req, Resp>
where
  Req: Message,
  Resp: Message,
{
  service_mapping: ServiceMapping,
  request_receiver: SimpleDataReaderR<RequestWrapper<Req>>,
  response_sender: DataWriterR<ResponseWrapper<Resp>>,
  // The node's matches of its writers with remote readers, kept by its Spinner;
  // `None` when the node had no Spinner when this server was made.
  matched_readers: Option<Arc<Mutex<BTreeMap<GUID, BTreeSet<GUID>>>>>,
}

/// How long [`Server::send_response`] waits for the requesting client's reply
/// reader to be matched before it sends anyway. rmw_cyclonedds and rmw_fastrtps
/// wait 100 ms; discovery on a loaded machine can take longer.
pub const REPLY_READER_WAIT: Duration = Duration::from_secs(1);

// Whether `reader` belongs to the participant that sent the request `client`
// names. The Cyclone mapping carries only the first 8 octets of the client's
// GUID prefix (the rest of its id is its own counter), so that much is compared.
fn same_participant(reader: &GUID, client: &GUID) -> bool {
  reader.prefix.as_ref()[..8] == client.prefix.as_ref()[..8]
}

impl<Req, Resp> Server<Req, Resp>
where
  Req: Message + 'static,
  Resp: Message + 'static,
{
  pub(crate) fn new(
    service_mapping: ServiceMapping,
    node: &mut Node,
    request_topic: &Topic,
    response_topic: &Topic,
    qos_request: Option<QosProfile>,
    qos_response: Option<QosProfile>,
  ) -> CreateResult<Self> {
    let request_receiver =
      node.create_simpledatareader
      ::<RequestWrapper<Req>, ServiceDeserializerAdapter<RequestWrapper<Req>>>(
        request_topic, qos_request)?;
    let response_sender = node
      .create_datawriter::<ResponseWrapper<Resp>, ServiceSerializerAdapter<ResponseWrapper<Resp>>>(
        response_topic,
        qos_response,
      )?;

    debug!(
      "Created new Server: requests={} response={}",
      request_topic.name(),
      response_topic.name()
    );

    let matched_readers = node
      .have_spinner()
      .then(|| node.writers_to_remote_readers());
    Ok(Server::<Req, Resp> {
      service_mapping,
      request_receiver,
      response_sender,
      matched_readers,
    })
  }

  /// Receive a request from Client.
  /// Returns `Ok(None)` if no new requests have arrived.
  pub fn receive_request(&self) -> ReadResult<Option<(RmwRequestId, Req)>> {
    self.request_receiver.drain_read_notifications();
    let dcc_rw: Option<no_key::DeserializedCacheChange<RequestWrapper<Req>>> =
      self.request_receiver.try_take_one()?;

    match dcc_rw {
      None => Ok(None),
      Some(dcc) => {
        let mi = MessageInfo::from(&dcc);
        let req_wrapper = dcc.into_value();
        let (ri, req) = req_wrapper.unwrap(self.service_mapping, &mi)?;
        Ok(Some((ri, req)))
      }
    } // match
  }

  /// Whether the reply writer has matched a reader of the client that sent
  /// `rmw_req_id`; `None` when matches are not tracked (no Spinner).
  ///
  /// A server that answers many clients from one thread can hold a reply
  /// until this says `true` (or its own deadline passes) and then send it with
  /// [`Server::send_response_now`], instead of blocking in
  /// [`Server::send_response`] while other clients wait.
  pub fn reply_reader_matched(&self, rmw_req_id: &RmwRequestId) -> Option<bool> {
    let matched = self.matched_readers.as_ref()?.lock().unwrap();
    let client = GUID::from(rmw_req_id.writer_gid);
    let readers = matched.get(&self.response_sender.guid());
    Some(readers.is_some_and(|readers| readers.iter().any(|r| same_participant(r, &client))))
  }

  /// Waits, up to [`REPLY_READER_WAIT`], until the reply writer has matched a
  /// reader of the requesting client. A client's first request can arrive
  /// before this side of discovery is done; a reply written then reaches no
  /// reader, and a volatile reader never gets it. Returns whether it matched.
  fn wait_for_client_reader(&self, rmw_req_id: &RmwRequestId) -> bool {
    let deadline = Instant::now() + REPLY_READER_WAIT;
    loop {
      match self.reply_reader_matched(rmw_req_id) {
        None | Some(true) => return true,
        Some(false) if Instant::now() >= deadline => return false,
        Some(false) => std::thread::sleep(Duration::from_millis(2)),
      }
    }
  }

  /// Send response to request by Client.
  /// rmw_req_id identifies request being responded.
  ///
  /// When the node has a Spinner, this first waits (up to
  /// [`REPLY_READER_WAIT`]) until a reply reader of the requesting client is
  /// matched, as rmw_cyclonedds and rmw_fastrtps do, then sends in any case.
  pub fn send_response(&self, rmw_req_id: RmwRequestId, response: Resp) -> WriteResult<(), ()> {
    if !self.wait_for_client_reader(&rmw_req_id) {
      warn!(
        "send_response: no reply reader of client {:?} matched within {REPLY_READER_WAIT:?}; sending anyway",
        rmw_req_id.writer_gid
      );
    }
    self.send_response_now(rmw_req_id, response)
  }

  /// Sends the response to the request `rmw_req_id` identifies at once, whether
  /// or not the client's reply reader is matched yet (see
  /// [`Server::reply_reader_matched`]).
  pub fn send_response_now(&self, rmw_req_id: RmwRequestId, response: Resp) -> WriteResult<(), ()> {
    let resp_wrapper = ResponseWrapper::<Resp>::new(
      self.service_mapping,
      rmw_req_id,
      RepresentationIdentifier::CDR_LE,
      response,
    )?;
    let write_opts = WriteOptionsBuilder::new()
      .source_timestamp(Timestamp::now()) // always add source timestamp
      .related_sample_identity(SampleIdentity::from(rmw_req_id))
      // TODO: Check if this is right. Cyclone mapping does not send
      // Related Sample Identity in
      // WriteOptions (QoS ParameterList), but within data payload.
      // But maybe it is not harmful to send it in both?
      .build();
    self
      .response_sender
      .write_with_options(resp_wrapper, write_opts)
      .map(|_| ())
      .map_err(|e| WriteError::from(e.forget_data())) // lose SampleIdentity
    // result
  }

  /// The request_id must be sent back with the response to identify which
  /// request and response belong together.
  pub async fn async_receive_request(&self) -> ReadResult<(RmwRequestId, Req)> {
    let dcc_stream = self.request_receiver.as_async_stream();
    pin_mut!(dcc_stream);

    match dcc_stream.next().await {
      Some(Err(e)) => Err(e.into()),
      Some(Ok(dcc)) => {
        let mi = MessageInfo::from(&dcc);
        let req_wrapper = dcc.into_value();
        let (ri, req) = req_wrapper.unwrap(self.service_mapping, &mi)?;
        debug!("async_receive_request: {ri:?}");
        Ok((ri, req))
      }
      // This should never occur, because topic do not "end".
      None => read_error_internal!("SimpleDataReader value stream unexpectedly ended!"),
    } // match
  }

  /// Returns a never-ending stream of (request_id, request)
  /// The request_id must be sent back with the response to identify which
  /// request and response belong together.
  pub fn receive_request_stream(
    &self,
  ) -> impl FusedStream<Item = ReadResult<(RmwRequestId, Req)>> + '_ {
    Box::pin(self.request_receiver.as_async_stream().then(
      move |dcc_r| async move {
        match dcc_r {
          Err(e) => Err(e.into()),
          Ok(dcc) => {
            let mi = MessageInfo::from(&dcc);
            let req_wrapper = dcc.into_value();
            debug!("receive_request_stream: messageinfo={mi:?}");
            req_wrapper.unwrap(self.service_mapping, &mi)
          }
        } // match
      }, // async
    ))
  }

  /// Asynchronous response sending
  ///
  /// Unlike [`Server::send_response`], this does not wait for the client's
  /// reply reader to be matched: the crate has no async timer to wait with
  /// whatever runtime calls it. A caller that may answer a client's first
  /// request should use `send_response`.
  pub async fn async_send_response(
    &self,
    rmw_req_id: RmwRequestId,
    response: Resp,
  ) -> WriteResult<(), ()> {
    let resp_wrapper = ResponseWrapper::<Resp>::new(
      self.service_mapping,
      rmw_req_id,
      RepresentationIdentifier::CDR_LE,
      response,
    )?;
    debug!("async_send_response: rmw_req_id = {rmw_req_id:?}");
    debug!(
      "async_send_response: related_sample_identity = {:?}",
      SampleIdentity::from(rmw_req_id)
    );
    let write_opts = WriteOptionsBuilder::new()
      .source_timestamp(Timestamp::now()) // always add source timestamp
      .related_sample_identity(SampleIdentity::from(rmw_req_id))
      // TODO: Check if this is right. Cyclone mapping does not send
      // Related Sample Identity in
      // WriteOptions (QoS ParameterList), but within data payload.
      // But maybe it is not harmful to send it in both?
      .build();
    self
      .response_sender
      .async_write_with_options(resp_wrapper, write_opts)
      .await
      .map(|_| ())
      .map_err(|e| WriteError::from(e.forget_data())) // lose SampleIdentity
    // result
  }
}

#[cfg(feature = "mio_06")]
impl<Req, Resp> Evented for Server<Req, Resp>
where
  Req: Message + 'static,
  Resp: Message + 'static,
{
  fn register(&self, poll: &Poll, token: Token, interest: Ready, opts: PollOpt) -> io::Result<()> {
    self.request_receiver.register(poll, token, interest, opts)
  }

  fn reregister(
    &self,
    poll: &Poll,
    token: Token,
    interest: Ready,
    opts: PollOpt,
  ) -> io::Result<()> {
    self
      .request_receiver
      .reregister(poll, token, interest, opts)
  }

  fn deregister(&self, poll: &Poll) -> io::Result<()> {
    self.request_receiver.deregister(poll)
  }
}

#[cfg(feature = "mio_1")]
impl<Req, Resp> mio1::event::Source for Server<Req, Resp>
where
  Req: Message + 'static,
  Resp: Message + 'static,
{
  fn register(
    &mut self,
    registry: &mio1::Registry,
    token: mio1::Token,
    interests: mio1::Interest,
  ) -> io::Result<()> {
    mio1::event::Source::register(&mut self.request_receiver, registry, token, interests)
  }

  fn reregister(
    &mut self,
    registry: &mio1::Registry,
    token: mio1::Token,
    interests: mio1::Interest,
  ) -> io::Result<()> {
    mio1::event::Source::reregister(&mut self.request_receiver, registry, token, interests)
  }

  fn deregister(&mut self, registry: &mio1::Registry) -> io::Result<()> {
    mio1::event::Source::deregister(&mut self.request_receiver, registry)
  }
}

#[cfg(test)]
mod tests {
  use super::*;

  fn guid(prefix: [u8; 12]) -> GUID {
    GUID::from_bytes(std::array::from_fn(|i| if i < 12 { prefix[i] } else { 0 }))
  }

  #[test]
  fn a_client_is_recognised_by_the_first_eight_octets_of_its_prefix() {
    let reader = guid([1, 15, 2, 3, 4, 5, 6, 7, 0, 0, 0, 9]);
    // The Cyclone mapping: the client's own counter in the last four octets.
    let cyclone_client = guid([1, 15, 2, 3, 4, 5, 6, 7, 0xaa, 0xbb, 0xcc, 0xdd]);
    assert!(same_participant(&reader, &cyclone_client));
    assert!(same_participant(&reader, &reader));
    let other = guid([1, 15, 2, 3, 4, 5, 6, 8, 0, 0, 0, 9]);
    assert!(!same_participant(&reader, &other));
  }
}
