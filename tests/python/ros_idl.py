"""ROS 2 message types declared independently for CycloneDDS Python.

These are written from the ROS 2 .msg definitions (not generated from our code), so a
field-exact exchange with them proves our wire format matches what rmw_cyclonedds
speaks: topic `rt/<name>`, type `<pkg>::msg::dds_::<Name>_`, XCDR1.
"""

from dataclasses import dataclass, field

from cyclonedds.core import Policy, Qos
from cyclonedds.idl import IdlStruct
from cyclonedds.idl import types as t


@dataclass
class Time(IdlStruct, typename="builtin_interfaces::msg::dds_::Time_"):
    sec: t.int32 = 0
    nanosec: t.uint32 = 0


@dataclass
class Header(IdlStruct, typename="std_msgs::msg::dds_::Header_"):
    stamp: Time = field(default_factory=Time)
    frame_id: str = ""


@dataclass
class JointState(IdlStruct, typename="sensor_msgs::msg::dds_::JointState_"):
    header: Header = field(default_factory=Header)
    name: t.sequence[str] = field(default_factory=list)
    position: t.sequence[t.float64] = field(default_factory=list)
    velocity: t.sequence[t.float64] = field(default_factory=list)
    effort: t.sequence[t.float64] = field(default_factory=list)


def ros_default_qos(depth: int = 10) -> Qos:
    """rclcpp's default profile (reliable, keep last 10, volatile), XCDR1 as ROS 2 uses."""
    return Qos(
        Policy.Reliability.Reliable(max_blocking_time=1_000_000_000),
        Policy.History.KeepLast(depth),
        Policy.Durability.Volatile,
        Policy.DataRepresentation(use_cdrv0_representation=True),
    )


@dataclass
class Point(IdlStruct, typename="geometry_msgs::msg::dds_::Point_"):
    x: t.float64 = 0.0
    y: t.float64 = 0.0
    z: t.float64 = 0.0


@dataclass
class Quaternion(IdlStruct, typename="geometry_msgs::msg::dds_::Quaternion_"):
    x: t.float64 = 0.0
    y: t.float64 = 0.0
    z: t.float64 = 0.0
    w: t.float64 = 1.0


@dataclass
class Pose(IdlStruct, typename="geometry_msgs::msg::dds_::Pose_"):
    position: Point = field(default_factory=Point)
    orientation: Quaternion = field(default_factory=Quaternion)


@dataclass
class PoseStamped(IdlStruct, typename="geometry_msgs::msg::dds_::PoseStamped_"):
    header: Header = field(default_factory=Header)
    pose: Pose = field(default_factory=Pose)


# --- causal_arm_msgs services as rmw_cyclonedds puts them on the wire ---------------------
# Request topic `rq/<service>Request`, reply topic `rr/<service>Reply`; each sample starts
# in-band with the request header (u64 client guid, i64 sequence number), then the fields.


@dataclass
class PredictNextStateRequest(IdlStruct, typename="causal_arm_msgs::srv::dds_::PredictNextState_Request_"):
    client_guid: t.uint64 = 0
    sequence_number: t.int64 = 0
    state: t.sequence[t.float64] = field(default_factory=list)
    action: t.sequence[t.float64] = field(default_factory=list)
    rows: t.uint32 = 0


@dataclass
class PredictNextStateReply(IdlStruct, typename="causal_arm_msgs::srv::dds_::PredictNextState_Response_"):
    client_guid: t.uint64 = 0
    sequence_number: t.int64 = 0
    success: bool = False
    message: str = ""
    next_state: t.sequence[t.float64] = field(default_factory=list)
    state_names: t.sequence[str] = field(default_factory=list)
    rows: t.uint32 = 0


@dataclass
class PredictActionRequest(IdlStruct, typename="causal_arm_msgs::srv::dds_::PredictAction_Request_"):
    client_guid: t.uint64 = 0
    sequence_number: t.int64 = 0
    state: t.sequence[t.float64] = field(default_factory=list)
    next_state: t.sequence[t.float64] = field(default_factory=list)
    rows: t.uint32 = 0


@dataclass
class PredictActionReply(IdlStruct, typename="causal_arm_msgs::srv::dds_::PredictAction_Response_"):
    client_guid: t.uint64 = 0
    sequence_number: t.int64 = 0
    success: bool = False
    message: str = ""
    action: t.sequence[t.float64] = field(default_factory=list)
    action_names: t.sequence[str] = field(default_factory=list)
    rows: t.uint32 = 0


@dataclass
class RolloutRequest(IdlStruct, typename="causal_arm_msgs::srv::dds_::Rollout_Request_"):
    client_guid: t.uint64 = 0
    sequence_number: t.int64 = 0
    initial_state: t.sequence[t.float64] = field(default_factory=list)
    actions: t.sequence[t.float64] = field(default_factory=list)
    steps: t.uint32 = 0


@dataclass
class RolloutReply(IdlStruct, typename="causal_arm_msgs::srv::dds_::Rollout_Response_"):
    client_guid: t.uint64 = 0
    sequence_number: t.int64 = 0
    success: bool = False
    message: str = ""
    states: t.sequence[t.float64] = field(default_factory=list)
    state_names: t.sequence[str] = field(default_factory=list)
    steps: t.uint32 = 0


@dataclass
class GetModelInfoRequest(IdlStruct, typename="causal_arm_msgs::srv::dds_::GetModelInfo_Request_"):
    client_guid: t.uint64 = 0
    sequence_number: t.int64 = 0
    model: str = ""


@dataclass
class GetModelInfoReply(IdlStruct, typename="causal_arm_msgs::srv::dds_::GetModelInfo_Response_"):
    client_guid: t.uint64 = 0
    sequence_number: t.int64 = 0
    success: bool = False
    message: str = ""
    models: t.sequence[str] = field(default_factory=list)
    state_names: t.sequence[str] = field(default_factory=list)
    action_names: t.sequence[str] = field(default_factory=list)
    next_state_names: t.sequence[str] = field(default_factory=list)
    metrics_json: str = ""


@dataclass
class ExplainRequest(IdlStruct, typename="causal_arm_msgs::srv::dds_::Explain_Request_"):
    client_guid: t.uint64 = 0
    sequence_number: t.int64 = 0
    method: str = ""
    state: t.sequence[t.float64] = field(default_factory=list)
    action: t.sequence[t.float64] = field(default_factory=list)
    rows: t.uint32 = 0
    background: t.uint32 = 0


@dataclass
class ExplainReply(IdlStruct, typename="causal_arm_msgs::srv::dds_::Explain_Response_"):
    client_guid: t.uint64 = 0
    sequence_number: t.int64 = 0
    success: bool = False
    message: str = ""
    attributions: t.sequence[t.float64] = field(default_factory=list)
    input_names: t.sequence[str] = field(default_factory=list)
    output_names: t.sequence[str] = field(default_factory=list)
    rows: t.uint32 = 0


@dataclass
class Relevance(IdlStruct, typename="causal_arm_msgs::msg::dds_::Relevance_"):
    header: Header = field(default_factory=Header)
    experiment: str = ""
    method: str = ""
    observations: t.uint32 = 0
    background: t.uint32 = 0
    action_names: t.sequence[str] = field(default_factory=list)
    state_names: t.sequence[str] = field(default_factory=list)
    mean_abs_shap: t.sequence[t.float64] = field(default_factory=list)
    state_scale: t.sequence[t.float64] = field(default_factory=list)
    affected: t.sequence[bool] = field(default_factory=list)
    threshold: t.float64 = 0.0
    rule: str = ""


def latched_qos(depth: int = 1) -> Qos:
    """rclcpp's transient-local profile for latched topics (/robot_description, reports)."""
    return Qos(
        Policy.Reliability.Reliable(max_blocking_time=1_000_000_000),
        Policy.History.KeepLast(depth),
        Policy.Durability.TransientLocal,
        Policy.DataRepresentation(use_cdrv0_representation=True),
    )


@dataclass
class FloatingPointRange(IdlStruct, typename="rcl_interfaces::msg::dds_::FloatingPointRange_"):
    from_value: t.float64 = 0.0
    to_value: t.float64 = 0.0
    step: t.float64 = 0.0


@dataclass
class IntegerRange(IdlStruct, typename="rcl_interfaces::msg::dds_::IntegerRange_"):
    from_value: t.int64 = 0
    to_value: t.int64 = 0
    step: t.uint64 = 0


@dataclass
class ParameterDescriptor(IdlStruct, typename="rcl_interfaces::msg::dds_::ParameterDescriptor_"):
    name: str = ""
    type: t.uint8 = 0
    description: str = ""
    additional_constraints: str = ""
    read_only: bool = False
    dynamic_typing: bool = False
    floating_point_range: t.sequence[FloatingPointRange, 1] = field(default_factory=list)
    integer_range: t.sequence[IntegerRange, 1] = field(default_factory=list)


@dataclass
class DescribeParametersRequest(IdlStruct, typename="rcl_interfaces::srv::dds_::DescribeParameters_Request_"):
    client_guid: t.uint64 = 0
    sequence_number: t.int64 = 0
    names: t.sequence[str] = field(default_factory=list)


@dataclass
class DescribeParametersReply(IdlStruct, typename="rcl_interfaces::srv::dds_::DescribeParameters_Response_"):
    client_guid: t.uint64 = 0
    sequence_number: t.int64 = 0
    descriptors: t.sequence[ParameterDescriptor] = field(default_factory=list)


@dataclass
class ParameterValue(IdlStruct, typename="rcl_interfaces::msg::dds_::ParameterValue_"):
    type: t.uint8 = 0
    bool_value: bool = False
    integer_value: t.int64 = 0
    double_value: t.float64 = 0.0
    string_value: str = ""
    byte_array_value: t.sequence[t.uint8] = field(default_factory=list)
    bool_array_value: t.sequence[bool] = field(default_factory=list)
    integer_array_value: t.sequence[t.int64] = field(default_factory=list)
    double_array_value: t.sequence[t.float64] = field(default_factory=list)
    string_array_value: t.sequence[str] = field(default_factory=list)


@dataclass
class Parameter(IdlStruct, typename="rcl_interfaces::msg::dds_::Parameter_"):
    name: str = ""
    value: ParameterValue = field(default_factory=ParameterValue)


@dataclass
class SetParametersResult(IdlStruct, typename="rcl_interfaces::msg::dds_::SetParametersResult_"):
    successful: bool = False
    reason: str = ""


@dataclass
class SetParametersRequest(IdlStruct, typename="rcl_interfaces::srv::dds_::SetParameters_Request_"):
    client_guid: t.uint64 = 0
    sequence_number: t.int64 = 0
    parameters: t.sequence[Parameter] = field(default_factory=list)


@dataclass
class SetParametersReply(IdlStruct, typename="rcl_interfaces::srv::dds_::SetParameters_Response_"):
    client_guid: t.uint64 = 0
    sequence_number: t.int64 = 0
    results: t.sequence[SetParametersResult] = field(default_factory=list)


class ServiceClient:
    """A ROS 2 service client as rmw_cyclonedds makes one, on a CycloneDDS participant."""

    def __init__(self, participant, service: str, request_type, reply_type):
        from cyclonedds.pub import DataWriter
        from cyclonedds.sub import DataReader
        from cyclonedds.topic import Topic

        name = service.lstrip("/")
        qos = ros_default_qos(depth=100)
        self.writer = DataWriter(participant, Topic(participant, f"rq/{name}Request", request_type), qos=qos)
        self.reader = DataReader(participant, Topic(participant, f"rr/{name}Reply", reply_type), qos=qos)
        self.guid = int.from_bytes(self.writer.guid.bytes[:8], "little")
        self.sequence = 0

    def wait_for_server(self, timeout: float = 20.0) -> bool:
        import time

        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            if self.writer.get_matched_subscriptions() and self.reader.get_matched_publications():
                time.sleep(0.5)  # let the server's reader match us too, as with topics
                return True
            time.sleep(0.05)
        return False

    def call(self, request, timeout: float = 10.0):
        import time

        self.sequence += 1
        request.client_guid = self.guid
        request.sequence_number = self.sequence
        self.writer.write(request)
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            for reply in self.reader.take(N=16):
                if reply.client_guid == self.guid and reply.sequence_number == self.sequence:
                    return reply
            time.sleep(0.0002)
        raise TimeoutError(f"no reply within {timeout} s")


@dataclass
class Draw(IdlStruct, typename="causal_arm_msgs::msg::dds_::Draw_"):
    """causal_arm_msgs/msg/Draw, written from msgs/msg/Draw.msg."""
    family: t.uint8 = 0
    center: t.float64 = 0.0
    scale: t.float64 = 0.0
    lower: t.float64 = 0.0
    upper: t.float64 = 0.0
    values: t.sequence[t.float64] = field(default_factory=list)
    probabilities: t.sequence[t.float64] = field(default_factory=list)
    tries: t.uint32 = 0
    min_tool_z: t.float64 = 0.0
    tool_area: t.sequence[t.float64] = field(default_factory=list)


@dataclass
class Action(IdlStruct, typename="causal_arm_msgs::msg::dds_::Action_"):
    """causal_arm_msgs/msg/Action, written from msgs/msg/Action.msg (a publisher of the
    layout before `design` was appended is not read over DDS, as ROS 2 itself matches types
    by their definition)."""
    header: Header = field(default_factory=Header)
    episode: t.uint32 = 0
    step: t.uint32 = 0
    joint_deltas: t.sequence[t.float64] = field(default_factory=list)
    joint_targets: t.sequence[t.float64] = field(default_factory=list)
    magnet: t.int8 = 0
    design: t.sequence[Draw] = field(default_factory=list)


@dataclass
class Gid(IdlStruct, typename="rmw_dds_common::msg::dds_::Gid_"):
    data: t.array[t.uint8, 16] = field(default_factory=lambda: [0] * 16)


@dataclass
class NodeEntitiesInfo(IdlStruct, typename="rmw_dds_common::msg::dds_::NodeEntitiesInfo_"):
    node_namespace: str = "/"
    node_name: str = ""
    reader_gid_seq: t.sequence[Gid] = field(default_factory=list)
    writer_gid_seq: t.sequence[Gid] = field(default_factory=list)


@dataclass
class ParticipantEntitiesInfo(IdlStruct, typename="rmw_dds_common::msg::dds_::ParticipantEntitiesInfo_"):
    """What every rmw publishes on `ros_discovery_info`: its participant's nodes and their
    readers' and writers' GIDs (rmw_dds_common, 16-byte GIDs since Iron)."""
    gid: Gid = field(default_factory=Gid)
    node_entities_info_seq: t.sequence[NodeEntitiesInfo] = field(default_factory=list)


def discovery_info_qos() -> Qos:
    """`ros_discovery_info` as rmw writes it: reliable, transient local, keep last 1."""
    return Qos(
        Policy.Reliability.Reliable(max_blocking_time=1_000_000_000),
        Policy.History.KeepLast(1),
        Policy.Durability.TransientLocal,
        Policy.DataRepresentation(use_cdrv0_representation=True),
    )


def gid_of(entity) -> Gid:
    """The rmw GID of a CycloneDDS entity: its 16-byte GUID."""
    return Gid(data=list(entity.guid.bytes))


@dataclass
class Clock(IdlStruct, typename="rosgraph_msgs::msg::dds_::Clock_"):
    clock: Time = field(default_factory=Time)


@dataclass
class RosString(IdlStruct, typename="std_msgs::msg::dds_::String_"):
    """std_msgs/msg/String (e.g. /robot_description)."""
    data: str = ""


@dataclass
class ColorRGBA(IdlStruct, typename="std_msgs::msg::dds_::ColorRGBA_"):
    r: t.float32 = 0.0
    g: t.float32 = 0.0
    b: t.float32 = 0.0
    a: t.float32 = 0.0


@dataclass
class ObjectColor(IdlStruct, typename="causal_arm_msgs::msg::dds_::ObjectColor_"):
    """causal_arm_msgs/msg/ObjectColor, written from msgs/msg/ObjectColor.msg."""
    header: Header = field(default_factory=Header)
    color: ColorRGBA = field(default_factory=ColorRGBA)


@dataclass
class MagnetState(IdlStruct, typename="causal_arm_msgs::msg::dds_::MagnetState_"):
    """causal_arm_msgs/msg/MagnetState, written from msgs/msg/MagnetState.msg."""
    header: Header = field(default_factory=Header)
    on: bool = False
    holding: bool = False


@dataclass
class Log(IdlStruct, typename="rcl_interfaces::msg::dds_::Log_"):
    """rcl_interfaces/msg/Log, what every node writes on /rosout."""
    stamp: Time = field(default_factory=Time)
    level: t.uint8 = 0
    name: str = ""
    msg: str = ""
    file: str = ""
    function: str = ""
    line: t.uint32 = 0
