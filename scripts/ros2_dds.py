"""The ROS 2 messages of `pneuflex ros2` as Eclipse Cyclone DDS sees them (the `cyclonedds` package,
scripts/requirements.txt), for scripts/check_ros2_node.py and scripts/bench_ros2_node.py: the IDL types ROS 2
generates for them (`pkg::msg::dds_::Type_`, the topic `rt/<name>`), Cyclone held to the loopback interface,
and the node started on a domain of its own.
"""
# No `from __future__ import annotations`: cyclonedds reads the field types at run time.
import os
import subprocess
from dataclasses import dataclass
from pathlib import Path

from cyclonedds.idl import IdlStruct
from cyclonedds.idl.types import float64, int32, sequence, uint32

# Discovery and traffic on 127.0.0.1 alone (lo has no multicast: the peers are found by unicast to the
# well-known ports of participant indices 0..20), as ROS_LOCALHOST_ONLY=1 does for a ROS 2 node.
LOOPBACK = (
    '<CycloneDDS><Domain Id="any"><General><Interfaces><NetworkInterface address="127.0.0.1"/></Interfaces>'
    "<AllowMulticast>false</AllowMulticast></General><Discovery><ParticipantIndex>auto</ParticipantIndex>"
    "<MaxAutoParticipantIndex>20</MaxAutoParticipantIndex><Peers><Peer address=\"127.0.0.1\"/></Peers>"
    "</Discovery></Domain></CycloneDDS>"
)


@dataclass
class Time(IdlStruct, typename="builtin_interfaces::msg::dds_::Time_"):
    sec: int32
    nanosec: uint32


@dataclass
class Header(IdlStruct, typename="std_msgs::msg::dds_::Header_"):
    stamp: Time
    frame_id: str


@dataclass
class JointState(IdlStruct, typename="sensor_msgs::msg::dds_::JointState_"):
    header: Header
    name: sequence[str]
    position: sequence[float64]
    velocity: sequence[float64]
    effort: sequence[float64]


@dataclass
class FluidPressure(IdlStruct, typename="sensor_msgs::msg::dds_::FluidPressure_"):
    header: Header
    fluid_pressure: float64
    variance: float64


@dataclass
class MultiArrayDimension(IdlStruct, typename="std_msgs::msg::dds_::MultiArrayDimension_"):
    label: str
    size: uint32
    stride: uint32


@dataclass
class MultiArrayLayout(IdlStruct, typename="std_msgs::msg::dds_::MultiArrayLayout_"):
    dim: sequence[MultiArrayDimension]
    data_offset: uint32


@dataclass
class Float64MultiArray(IdlStruct, typename="std_msgs::msg::dds_::Float64MultiArray_"):
    layout: MultiArrayLayout
    data: sequence[float64]


@dataclass
class Clock(IdlStruct, typename="rosgraph_msgs::msg::dds_::Clock_"):
    clock: Time


def stamp_ns(t: Time) -> int:
    return t.sec * 1_000_000_000 + t.nanosec


def use_loopback() -> None:
    """Cyclone on 127.0.0.1 alone; call before the first DomainParticipant."""
    os.environ["CYCLONEDDS_URI"] = LOOPBACK


def domain_of_pid() -> int:
    """A domain unlikely to be another test's: 1..100 from the process id (0 is every ROS 2 default)."""
    return 1 + os.getpid() % 100


def start_node(pneuflex: str, scene: str, run: str, duration_s: float, domain: int, out: Path,
               *extra: str) -> "subprocess.Popen[bytes]":
    """`pneuflex ros2 SCENE --run RUN --duration S --domain-id N --localhost --out OUT`; its output in
    OUT.log."""
    log = open(f"{out}.log", "w")
    return subprocess.Popen(
        [pneuflex, "ros2", scene, "--run", run, "--duration", str(duration_s), "--domain-id", str(domain),
         "--localhost", "--out", str(out), *extra],
        stdout=log, stderr=subprocess.STDOUT)
