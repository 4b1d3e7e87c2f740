// Every conversion between the daemon's own types and rheo.v1 messages, in one place: the
// services call these and never spell a message field by field themselves.
#pragma once

#include <array>
#include <string>
#include <utility>
#include <vector>

#include "common/geometry.h"
#include "daemon/api/lease.h"
#include "daemon/api/scene.h"
#include "daemon/device/device_link.h"
#include "daemon/loop/engine.h"
#include "rheo/v1/daemon.pb.h"
#include "rheo/v1/device.pb.h"
#include "rheo/v1/frames.pb.h"
#include "rheo/v1/objects.pb.h"
#include "rheo/v1/scene.pb.h"
#include "rt/histogram.h"
#include "sim/params.h"

namespace rheo::mesh {
struct MeshResult;
}
namespace rheo::sketch {
struct ContourOptions;
struct ContourResult;
}  // namespace rheo::sketch

namespace rheo::daemon {

void SetVec(const std::array<double, 3>& a, v1::Vec3* out);
void SetVec(const Vec3& a, v1::Vec3* out);
Vec3 ToVec(const std::array<double, 3>& a);
void SetQuaternion(const std::array<double, 4>& wxyz, v1::Quat* out);

v1::Integrator ToProto(sim::Integrator integrator);
/// Every parameter of the table with its value, unit, range and description.
void FillParameters(const sim::Parameters& p,
                    google::protobuf::RepeatedPtrField<v1::Parameter>* out);
void FillSceneObject(const SceneEntry& e, bool sleeping, bool unstable, v1::SceneObject* out);

/// A loop histogram as percentiles [us].
void FillPercentiles(const rt::Histogram& h, v1::Percentiles* out);

/// Spells the device's faults for people: the driver's bits plus the daemon's stop states.
std::vector<std::string> DeviceFaultList(const ToolTelemetry& t);
/// The tool in a frame: the visible haptic pointer.
void FillToolState(const ToolTelemetry& t, const std::string& lease_holder, v1::ToolState* out);
/// `lease` is (holder, seconds left).
void FillDeviceStatus(const DeviceLink& link, v1::DeviceKind kind, const ToolTelemetry& t,
                      const std::pair<std::string, double>& lease, const rt::LoopStats& loop,
                      v1::DeviceStatus* out);
void FillLease(const LeaseManager::Lease& l, v1::Lease* out);

sketch::ContourOptions ToSketchOptions(const v1::ContourOptions& o);
void FillContourReport(const sketch::ContourResult& r, v1::ContourReport* out);
void FillMeshReport(const mesh::MeshResult& r, v1::MeshReport* out);

}  // namespace rheo::daemon
