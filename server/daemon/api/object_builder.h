// Sketch -> contour -> solid for one CreateObject request, with progress, outside the loop.
#pragma once

#include <functional>
#include <optional>
#include <string>

#include "common/cancel.h"
#include "common/status.h"
#include "daemon/store/store.h"
#include "rheo/v1/objects.pb.h"

namespace rheo::daemon {

/// Hard limits the daemon puts on every object build.
struct BuildLimits {
  int64_t max_tets = 500000;
  int64_t max_vertices = 200000;
};

/// Reports progress; returns an error to stop the build (cancelled, deadline).
using BuildProgress = std::function<std::optional<Error>(const rheo::v1::CreateObjectProgress&)>;

/// Checks a request before any work is queued: INVALID_ARGUMENT names the field and its range.
Status ValidateCreateRequest(const rheo::v1::CreateObjectRequest& request);

/// A background photo must decode as PNG or JPEG within a sketch picture's limits
/// (INVALID_ARGUMENT or RESOURCE_EXHAUSTED naming background_image); empty is fine.
Status CheckBackgroundImage(const std::string& bytes);

/// Runs the whole build; the result is ready to store (id and creation time set). `cancel` is
/// polled inside the sketch and mesh stages' loops (kCancelled, kDeadlineExceeded).
Result<StoredObject> BuildObject(const rheo::v1::CreateObjectRequest& request,
                                 const BuildLimits& limits, const BuildProgress& progress,
                                 const CancelToken& cancel = CancelToken());

/// Only the sketch stage, for previews; the same limits and cancellation as BuildObject.
Result<rheo::v1::ContourReport> ExtractContour(const rheo::v1::Sketch& sketch,
                                               const rheo::v1::ContourOptions& options,
                                               const CancelToken& cancel = CancelToken());

}  // namespace rheo::daemon
