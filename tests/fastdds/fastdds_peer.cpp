// A Fast DDS peer that talks to the causal-arm graph as rmw_fastrtps does: the same topic and
// type names, the same QoS (reliable, volatile, keep-last, asynchronous publication) and the
// same request/reply correlation (the client sends its reply reader's GUID as the request's
// related sample identity; the server answers with the request's identity and first waits
// until that reader is matched).
//
// Payloads cross the command line as hex of the whole serialized sample (CDR encapsulation
// included), so the test that drives this program encodes and decodes messages with an
// independent CDR implementation and this program stays type-agnostic, like rmw_fastrtps's
// serialized-message API.
//
//   fastdds_peer sub   TOPIC TYPE COUNT TIMEOUT_S [IDLE_S]
//        prints COUNT samples, one hex line each; with IDLE_S, stops early once samples have
//        begun and none came for IDLE_S seconds (a volatile reader that matched after the
//        writer began cannot know how many it missed)
//   fastdds_peer pub   TOPIC TYPE TIMEOUT_S              publishes each hex line of stdin
//   fastdds_peer call  SERVICE REQ_TYPE REP_TYPE TIMEOUT_S
//        sends every hex line of stdin as one request, all before any reply, then prints
//        "INDEX HEX" for each reply, matched to its request by related sample identity
//   fastdds_peer serve SERVICE REQ_TYPE REP_TYPE COUNT TIMEOUT_S REPLY_HEX
//        answers COUNT requests with REPLY_HEX, printing each request's hex
//   fastdds_peer discover SECONDS
//        prints "writer|reader TOPIC TYPE USER_DATA_HEX" for every endpoint discovered
//
// Exit codes: 0 done, 1 timeout or protocol error (explained on stderr), 2 usage.
// ROS_DOMAIN_ID selects the domain, as for ROS 2.

#include <fastdds/dds/domain/DomainParticipant.hpp>
#include <fastdds/dds/domain/DomainParticipantFactory.hpp>
#include <fastdds/dds/domain/DomainParticipantListener.hpp>
#include <fastdds/rtps/builtin/data/ReaderProxyData.h>
#include <fastdds/rtps/builtin/data/WriterProxyData.h>
#include <fastdds/dds/publisher/DataWriter.hpp>
#include <fastdds/dds/publisher/DataWriterListener.hpp>
#include <fastdds/dds/publisher/Publisher.hpp>
#include <fastdds/dds/subscriber/DataReader.hpp>
#include <fastdds/dds/subscriber/SampleInfo.hpp>
#include <fastdds/dds/subscriber/Subscriber.hpp>
#include <fastdds/dds/topic/TopicDataType.hpp>
#include <fastdds/dds/topic/TypeSupport.hpp>
#include <fastdds/rtps/common/InstanceHandle.h>
#include <fastdds/rtps/common/WriteParams.h>

#include <chrono>
#include <cstdlib>
#include <cstring>
#include <iostream>
#include <map>
#include <mutex>
#include <set>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

using namespace eprosima::fastdds::dds;
using eprosima::fastrtps::rtps::GUID_t;
using eprosima::fastrtps::rtps::SampleIdentity;
using eprosima::fastrtps::rtps::SerializedPayload_t;
using eprosima::fastrtps::rtps::WriteParams;
using Clock = std::chrono::steady_clock;

namespace {

/// One serialized sample, kept as the bytes that travel (encapsulation header first).
struct RawSample {
  std::vector<uint8_t> bytes;
};

/// A type that moves serialized samples unchanged under a ROS 2 DDS type name.
class RawType : public TopicDataType {
 public:
  explicit RawType(const std::string& name) {
    setName(name.c_str());
    m_typeSize = 4096;  // initial allocation; samples grow as needed (realloc memory mode)
    m_isGetKeyDefined = false;
  }
  bool serialize(void* data, SerializedPayload_t* payload) override {
    auto* raw = static_cast<RawSample*>(data);
    if (raw->bytes.size() > payload->max_size) payload->reserve(raw->bytes.size());
    std::memcpy(payload->data, raw->bytes.data(), raw->bytes.size());
    payload->length = static_cast<uint32_t>(raw->bytes.size());
    payload->encapsulation = raw->bytes.size() > 1 && raw->bytes[1] == 0 ? CDR_BE : CDR_LE;
    return true;
  }
  bool deserialize(SerializedPayload_t* payload, void* data) override {
    auto* raw = static_cast<RawSample*>(data);
    raw->bytes.assign(payload->data, payload->data + payload->length);
    return true;
  }
  std::function<uint32_t()> getSerializedSizeProvider(void* data) override {
    auto size = static_cast<uint32_t>(static_cast<RawSample*>(data)->bytes.size());
    return [size]() { return size; };
  }
  void* createData() override { return new RawSample(); }
  void deleteData(void* data) override { delete static_cast<RawSample*>(data); }
  bool getKey(void*, eprosima::fastrtps::rtps::InstanceHandle_t*, bool) override { return false; }
};

std::string to_hex(const std::vector<uint8_t>& bytes) {
  static const char* digits = "0123456789abcdef";
  std::string out(bytes.size() * 2, '0');
  for (size_t i = 0; i < bytes.size(); ++i) {
    out[2 * i] = digits[bytes[i] >> 4];
    out[2 * i + 1] = digits[bytes[i] & 15];
  }
  return out;
}

bool from_hex(const std::string& text, std::vector<uint8_t>& out) {
  if (text.size() % 2 != 0) return false;
  out.resize(text.size() / 2);
  for (size_t i = 0; i < out.size(); ++i) {
    char* end = nullptr;
    std::string pair = text.substr(2 * i, 2);
    out[i] = static_cast<uint8_t>(std::strtoul(pair.c_str(), &end, 16));
    if (end != pair.c_str() + 2) return false;
  }
  return true;
}

std::vector<RawSample> read_hex_lines() {
  std::vector<RawSample> samples;
  std::string line;
  while (std::getline(std::cin, line)) {
    if (line.empty()) continue;
    RawSample sample;
    if (!from_hex(line, sample.bytes)) {
      std::cerr << "stdin line " << samples.size() + 1 << ": not hex\n";
      std::exit(2);
    }
    samples.push_back(std::move(sample));
  }
  return samples;
}

std::string guid_text(const GUID_t& guid) {
  std::ostringstream s;
  s << guid;
  return s.str();
}

/// Tracks which remote readers a writer is matched with, as rmw_fastrtps's service
/// publisher listener does, so a server can wait for a client's reply reader.
class MatchedReaders : public DataWriterListener {
 public:
  void on_publication_matched(DataWriter*, const PublicationMatchedStatus& info) override {
    GUID_t guid = eprosima::fastrtps::rtps::iHandle2GUID(info.last_subscription_handle);
    std::lock_guard<std::mutex> lock(mutex_);
    if (info.current_count_change > 0) {
      guids_.insert(guid);
    } else {
      guids_.erase(guid);
    }
  }
  bool has(const GUID_t& guid) {
    std::lock_guard<std::mutex> lock(mutex_);
    return guids_.count(guid) > 0;
  }

 private:
  std::mutex mutex_;
  std::set<GUID_t> guids_;
};

/// Prints every remote endpoint as discovery reports it, with its USER_DATA (where
/// ROS 2 endpoints announce `typehash=RIHS01_...;`, REP-2011).
class DiscoveryPrinter : public DomainParticipantListener {
 public:
  void on_publisher_discovery(DomainParticipant*,
                              eprosima::fastrtps::rtps::WriterDiscoveryInfo&& info) override {
    if (info.status == eprosima::fastrtps::rtps::WriterDiscoveryInfo::DISCOVERED_WRITER) {
      print("writer", info.info.topicName().to_string(), info.info.typeName().to_string(),
            info.info.m_qos.m_userData.data_vec());
    }
  }
  void on_subscriber_discovery(DomainParticipant*,
                               eprosima::fastrtps::rtps::ReaderDiscoveryInfo&& info) override {
    if (info.status == eprosima::fastrtps::rtps::ReaderDiscoveryInfo::DISCOVERED_READER) {
      print("reader", info.info.topicName().to_string(), info.info.typeName().to_string(),
            info.info.m_qos.m_userData.data_vec());
    }
  }

 private:
  void print(const char* kind, const std::string& topic, const std::string& type,
             const std::vector<uint8_t>& user_data) {
    std::lock_guard<std::mutex> lock(mutex_);
    std::cout << kind << " " << topic << " " << type << " " << to_hex(user_data) << std::endl;
  }
  std::mutex mutex_;
};

/// The participant and its entities; created once per run and torn down at exit.
struct Peer {
  DomainParticipant* participant = nullptr;
  Publisher* publisher = nullptr;
  Subscriber* subscriber = nullptr;

  explicit Peer(DomainParticipantListener* listener = nullptr) {
    int domain = 0;
    if (const char* env = std::getenv("ROS_DOMAIN_ID")) domain = std::atoi(env);
    DomainParticipantQos qos = PARTICIPANT_QOS_DEFAULT;
    qos.name("fastdds_peer");
    std::string enclave = "enclave=/;";  // what rmw_fastrtps announces in USER_DATA
    qos.user_data().data_vec(std::vector<uint8_t>(enclave.begin(), enclave.end()));
    participant = DomainParticipantFactory::get_instance()->create_participant(domain, qos, listener);
    if (participant == nullptr) fail("cannot create the Fast DDS participant");
    publisher = participant->create_publisher(PUBLISHER_QOS_DEFAULT);
    subscriber = participant->create_subscriber(SUBSCRIBER_QOS_DEFAULT);
  }
  ~Peer() {
    participant->delete_contained_entities();
    DomainParticipantFactory::get_instance()->delete_participant(participant);
  }

  [[noreturn]] static void fail(const std::string& why) {
    std::cerr << "fastdds_peer: " << why << "\n";
    std::exit(1);
  }

  Topic* topic(const std::string& name, const std::string& type_name) {
    TypeSupport type(new RawType(type_name));
    if (participant->register_type(type) != ReturnCode_t::RETCODE_OK) {
      fail("cannot register type " + type_name);
    }
    Topic* t = participant->create_topic(name, type_name, TOPIC_QOS_DEFAULT);
    if (t == nullptr) fail("cannot create topic " + name);
    return t;
  }

  DataWriter* writer(const std::string& name, const std::string& type_name, int depth,
                     DataWriterListener* listener = nullptr) {
    DataWriterQos qos = DATAWRITER_QOS_DEFAULT;
    qos.reliability().kind = RELIABLE_RELIABILITY_QOS;
    qos.durability().kind = VOLATILE_DURABILITY_QOS;
    qos.history().kind = KEEP_LAST_HISTORY_QOS;
    qos.history().depth = depth;
    qos.publish_mode().kind = ASYNCHRONOUS_PUBLISH_MODE;  // rmw_fastrtps's default
    qos.endpoint().history_memory_policy =
        eprosima::fastrtps::rtps::PREALLOCATED_WITH_REALLOC_MEMORY_MODE;
    qos.data_sharing().off();
    DataWriter* w = publisher->create_datawriter(topic(name, type_name), qos, listener);
    if (w == nullptr) fail("cannot create a writer on " + name);
    return w;
  }

  DataReader* reader(const std::string& name, const std::string& type_name, int depth) {
    DataReaderQos qos = DATAREADER_QOS_DEFAULT;
    qos.reliability().kind = RELIABLE_RELIABILITY_QOS;
    qos.durability().kind = VOLATILE_DURABILITY_QOS;
    qos.history().kind = KEEP_LAST_HISTORY_QOS;
    qos.history().depth = depth;
    qos.endpoint().history_memory_policy =
        eprosima::fastrtps::rtps::PREALLOCATED_WITH_REALLOC_MEMORY_MODE;
    qos.data_sharing().off();
    DataReader* r = subscriber->create_datareader(topic(name, type_name), qos);
    if (r == nullptr) fail("cannot create a reader on " + name);
    return r;
  }
};

bool wait_until(Clock::time_point deadline, const std::function<bool()>& ready) {
  while (!ready()) {
    if (Clock::now() > deadline) return false;
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  return true;
}

int writer_matches(DataWriter* w) {
  PublicationMatchedStatus s;
  w->get_publication_matched_status(s);
  return s.current_count;
}

int reader_matches(DataReader* r) {
  SubscriptionMatchedStatus s;
  r->get_subscription_matched_status(s);
  return s.current_count;
}

/// Takes the next valid sample within the deadline.
bool take(DataReader* reader, Clock::time_point deadline, RawSample& sample, SampleInfo& info) {
  while (Clock::now() < deadline) {
    while (reader->take_next_sample(&sample, &info) == ReturnCode_t::RETCODE_OK) {
      if (info.valid_data) return true;
    }
    reader->wait_for_unread_message(eprosima::fastrtps::Duration_t(0, 50000000));
  }
  return false;
}

int64_t sequence_of(const SampleIdentity& id) { return id.sequence_number().to64long(); }

int run_sub(Peer& peer, int argc, char** argv, Clock::time_point deadline) {
  int count = std::atoi(argv[4]);
  auto idle = std::chrono::milliseconds(argc > 6 ? static_cast<long>(std::atof(argv[6]) * 1000) : 0);
  // Deep enough that a slow take never overwrites an unread sample.
  DataReader* reader = peer.reader(argv[2], argv[3], std::max(100, count));
  RawSample sample;
  SampleInfo info;
  for (int got = 0; got < count; ++got) {
    auto until = deadline;
    if (got > 0 && idle.count() > 0) until = std::min(deadline, Clock::now() + idle);
    if (!take(reader, until, sample, info)) {
      if (got > 0 && until < deadline) {
        std::cerr << "idle after " << got << " of " << count << " samples on " << argv[2] << "\n";
        return 0;
      }
      Peer::fail("timeout after " + std::to_string(got) + " of " + std::to_string(count) +
                 " samples on " + argv[2]);
    }
    std::cout << to_hex(sample.bytes) << std::endl;
  }
  return 0;
}

int run_pub(Peer& peer, char** argv, Clock::time_point deadline) {
  std::vector<RawSample> samples = read_hex_lines();
  DataWriter* writer = peer.writer(argv[2], argv[3], std::max<int>(10, samples.size()));
  if (!wait_until(deadline, [&] { return writer_matches(writer) > 0; })) {
    Peer::fail(std::string("no reader of ") + argv[2] + " matched");
  }
  std::this_thread::sleep_for(std::chrono::milliseconds(300));  // let every reader match
  for (auto& sample : samples) {
    if (!writer->write(&sample)) Peer::fail("write failed");
  }
  auto left = std::chrono::duration_cast<std::chrono::seconds>(deadline - Clock::now()).count();
  if (writer->wait_for_acknowledgments(eprosima::fastrtps::Duration_t(std::max<long>(left, 1), 0)) !=
      ReturnCode_t::RETCODE_OK) {
    Peer::fail("samples not acknowledged in time");
  }
  std::cerr << "published " << samples.size() << " samples, matched "
            << writer_matches(writer) << " readers\n";
  return 0;
}

int run_call(Peer& peer, char** argv, Clock::time_point deadline) {
  std::string service = argv[2];
  std::vector<RawSample> requests = read_hex_lines();
  int depth = std::max<int>(10, requests.size());
  DataReader* replies = peer.reader("rr" + service + "Reply", argv[4], depth);
  DataWriter* writer = peer.writer("rq" + service + "Request", argv[3], depth);
  if (!wait_until(deadline, [&] { return writer_matches(writer) > 0 && reader_matches(replies) > 0; })) {
    Peer::fail("no server of " + service + " matched");
  }
  std::map<int64_t, size_t> index_of_sequence;
  for (size_t i = 0; i < requests.size(); ++i) {
    WriteParams params;
    params.related_sample_identity().writer_guid(replies->guid());  // as rmw_fastrtps clients
    if (!writer->write(&requests[i], params)) Peer::fail("request write failed");
    index_of_sequence[sequence_of(params.sample_identity())] = i;
  }
  std::set<size_t> answered;
  RawSample reply;
  SampleInfo info;
  while (answered.size() < requests.size()) {
    if (!take(replies, deadline, reply, info)) {
      // Say which direction stalled: were the requests acknowledged by the server?
      bool acked = writer->wait_for_acknowledgments(eprosima::fastrtps::Duration_t(0, 0)) ==
                   ReturnCode_t::RETCODE_OK;
      Peer::fail("timeout: " + std::to_string(answered.size()) + " of " +
                 std::to_string(requests.size()) + " replies (requests " +
                 (acked ? "acknowledged" : "NOT all acknowledged") + " by the server; " +
                 std::to_string(writer_matches(writer)) + " request readers and " +
                 std::to_string(reader_matches(replies)) + " reply writers matched)");
    }
    const SampleIdentity& related = info.related_sample_identity;
    bool ours = related.writer_guid() == replies->guid() || related.writer_guid() == writer->guid();
    auto found = index_of_sequence.find(sequence_of(related));
    if (!ours || found == index_of_sequence.end()) {
      Peer::fail("a reply for a request we did not send: " + guid_text(related.writer_guid()) +
                 " #" + std::to_string(sequence_of(related)));
    }
    if (!answered.insert(found->second).second) {
      Peer::fail("two replies to request " + std::to_string(found->second));
    }
    std::cout << found->second << " " << to_hex(reply.bytes) << std::endl;
  }
  return 0;
}

int run_serve(Peer& peer, char** argv, Clock::time_point deadline) {
  std::string service = argv[2];
  int count = std::atoi(argv[5]);
  RawSample answer;
  if (!from_hex(argv[7], answer.bytes)) Peer::fail("REPLY_HEX is not hex");
  MatchedReaders matched;
  DataReader* requests = peer.reader("rq" + service + "Request", argv[3], 100);
  DataWriter* writer = peer.writer("rr" + service + "Reply", argv[4], 100, &matched);
  RawSample request;
  SampleInfo info;
  for (int served = 0; served < count; ++served) {
    if (!take(requests, deadline, request, info)) {
      Peer::fail("timeout after " + std::to_string(served) + " of " + std::to_string(count) +
                 " requests");
    }
    // rmw_fastrtps: answer to the client's reply reader when the request names it, after
    // waiting until that reader is matched; otherwise to the request writer's identity.
    SampleIdentity reply_to = info.sample_identity;
    GUID_t reader = info.related_sample_identity.writer_guid();
    if (reader != GUID_t::unknown()) {
      reply_to.writer_guid(reader);
      if (!wait_until(deadline, [&] { return matched.has(reader); })) {
        Peer::fail("the client's reply reader " + guid_text(reader) + " never matched");
      }
    }
    WriteParams params;
    params.related_sample_identity(reply_to);
    if (!writer->write(&answer, params)) Peer::fail("reply write failed");
    std::cout << (reader != GUID_t::unknown() ? "reader " : "writer ") << to_hex(request.bytes)
              << std::endl;
  }
  // Let the last reply be acknowledged, briefly: a client that got it may already be gone,
  // and its reader stays matched until its lease ends.
  writer->wait_for_acknowledgments(eprosima::fastrtps::Duration_t(2, 0));
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  std::string mode = argc > 1 ? argv[1] : "";
  const std::map<std::string, int> arity = {
      {"sub", 7}, {"pub", 5}, {"call", 6}, {"serve", 8}, {"discover", 3}};
  auto want = arity.find(mode);
  bool optional_idle = mode == "sub" && argc == 6;
  if (want == arity.end() || (argc != want->second && !optional_idle)) {
    std::cerr << "usage: fastdds_peer sub TOPIC TYPE COUNT TIMEOUT_S [IDLE_S] | pub TOPIC TYPE TIMEOUT_S"
                 " | call SERVICE REQ_TYPE REP_TYPE TIMEOUT_S"
                 " | serve SERVICE REQ_TYPE REP_TYPE COUNT TIMEOUT_S REPLY_HEX | discover SECONDS\n";
    return 2;
  }
  double timeout = std::atof(argv[mode == "serve" ? 6 : mode == "sub" ? 5 : argc - 1]);
  auto deadline = Clock::now() + std::chrono::milliseconds(static_cast<long>(timeout * 1000));
  if (mode == "discover") {
    DiscoveryPrinter printer;
    Peer peer(&printer);
    std::this_thread::sleep_until(deadline);
    peer.participant->set_listener(nullptr);
    return 0;
  }
  Peer peer;
  if (mode == "sub") return run_sub(peer, argc, argv, deadline);
  if (mode == "pub") return run_pub(peer, argv, deadline);
  if (mode == "call") return run_call(peer, argv, deadline);
  return run_serve(peer, argv, deadline);
}
