#include "nn/obs_store.hpp"

#include "nn/kernels.hpp"

#include <cstring>

namespace hns::nn {

int axis_entities(const ObsShape& s, ObsAxis axis) {
  switch (axis) {
    case kObsRowAxis:
      return 1;
    case kObsAgentAxis:
      return s.num_other_agents();
    case kObsBoxAxis:
      return s.max_boxes;
    case kObsRampAxis:
      return s.max_ramps;
    case kObsSiteAxis:
      return s.max_sites;
  }
  HNS_NN_CHECK(false, "unknown observation axis");
  return 0;
}

int key_features(const ObsShape& s, int key) {
  switch (key) {
    case kObsMaskKey:
      return 1;
    case kObsSelf:
      return s.self_features;
    case kObsLidar:
      return s.lidar_rays;
    case kObsAgents:
      return s.agent_features;
    case kObsBoxes:
      return s.box_features;
    case kObsRamps:
      return s.ramp_features;
    case kObsSites:
      return s.site_features;
    default:
      break;
  }
  HNS_NN_CHECK(false, "unknown observation key");
  return 0;
}

std::vector<int> row_dims(const ObsShape& s, const ObsField& f) {
  std::vector<int> dims;
  if (f.axis != kObsRowAxis) dims.push_back(axis_entities(s, f.axis));
  if (!f.mask) dims.push_back(key_features(s, f.key));
  return dims;
}

namespace {

// A feature field's pointer from agent row `row` on, under its key; masks have no key.
void put_features(std::array<const float*, kNumObsKeys>& by_key, const float* p, const ObsField& f,
                  const ObsShape& s, size_t row) {
  by_key[size_t(f.key)] = p == nullptr ? nullptr : p + row * row_values(s, f);
}
void put_features(std::array<const float*, kNumObsKeys>&, const uint8_t*, const ObsField&, const ObsShape&,
                  size_t) {}

}  // namespace

std::array<const float*, kNumObsKeys> StepObs::features_from(size_t row, const ObsShape& s) const {
  std::array<const float*, kNumObsKeys> by_key{};
#define HNS_OBS_FEATURES_FROM(name, member, type, axis, key) \
  put_features(by_key, name, HNS_OBS_FIELD_INFO(name, member, type, axis, key), s, row);
  HNS_OBS_FIELDS(HNS_OBS_FEATURES_FROM)
#undef HNS_OBS_FEATURES_FROM
  return by_key;
}

void ObsStore::allocate(const ObsShape& shape, size_t rows) {
  shape_ = shape;
  rows_ = rows;
#define HNS_OBS_ALLOCATE(name, member, type, axis, key) \
  member.resize(rows* row_values(shape, HNS_OBS_FIELD_INFO(name, member, type, axis, key)));
  HNS_OBS_FIELDS(HNS_OBS_ALLOCATE)
#undef HNS_OBS_ALLOCATE
  reset.resize(rows);
}

size_t ObsStore::floats_per_row(const ObsShape& shape) {
  size_t floats = 1;  // the reset flag
  for (const ObsField& f : kObsFieldList) floats += row_values(shape, f);
  return floats;
}

namespace {

// Rows [row0, row0 + rows) of `dst` from a step's feature array, normalised and clipped with key `key`'s
// statistics when `norm` is given.
void copy_features(FloatBuffer& dst, const float* src, size_t rows, size_t row0, size_t entities,
                   size_t features, const ObsNormView* norm, int key) {
  const size_t per_row = entities * features;
  if (per_row == 0) return;
  float* to = dst.data() + row0 * per_row;
  if (norm == nullptr) {
    std::memcpy(to, src, sizeof(float) * rows * per_row);
  } else {
    kernels::normalize_obs(src, norm->mean[size_t(key)], norm->inv_std[size_t(key)], nullptr,
                           int(rows * entities), int(features), to);
  }
}

// Rows [row0, row0 + rows) of `dst` from a step's 0/1 mask bytes.
void widen_mask(FloatBuffer& dst, const uint8_t* src, size_t rows, size_t row0, size_t per_row) {
  float* d = dst.data() + row0 * per_row;
  for (size_t i = 0; i < rows * per_row; ++i) d[i] = float(src[i]);
}

void copy_field(FloatBuffer& dst, const float* src, const ObsField& f, const ObsShape& s, size_t rows,
                size_t row0, const ObsNormView* norm) {
  copy_features(dst, src, rows, row0, size_t(axis_entities(s, f.axis)), size_t(key_features(s, f.key)), norm,
                f.key);
}
void copy_field(FloatBuffer& dst, const uint8_t* src, const ObsField& f, const ObsShape& s, size_t rows,
                size_t row0, const ObsNormView*) {
  widen_mask(dst, src, rows, row0, row_values(s, f));
}

}  // namespace

void ObsStore::copy_step(const StepObs& step, size_t rows, size_t row0, const ObsNormView* norm) {
  HNS_NN_CHECK(row0 + rows <= rows_, "observation rows beyond the store");
#define HNS_OBS_COPY(name, member, type, axis, key) \
  copy_field(member, step.name, HNS_OBS_FIELD_INFO(name, member, type, axis, key), shape_, rows, row0, norm);
  HNS_OBS_FIELDS(HNS_OBS_COPY)
#undef HNS_OBS_COPY
}

ObsBatch ObsStore::batch() const {
  ObsBatch b;
#define HNS_OBS_VIEW(name, member, type, axis, key) b.member = member.data();
  HNS_OBS_FIELDS(HNS_OBS_VIEW)
#undef HNS_OBS_VIEW
  b.reset = reset.data();
  return b;
}

}  // namespace hns::nn
