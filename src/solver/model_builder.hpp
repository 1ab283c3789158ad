// Builds a validated Model from a plain description (used by the JSON loader,
// the built-in models and the tests). Throws ModelError at setup time only.
#pragma once

#include <Eigen/Core>
#include <stdexcept>
#include <string>
#include <vector>

#include "model.hpp"

namespace fabrik {

struct PointSpec {
  std::string name;
  Eigen::Vector3d p_local_m{0, 0, 0};  // relative to the segment base, rest frame
  bool marker = false;                 // a marker site rather than a joint / end site
};

struct SegmentSpec {
  std::string name;
  std::string parent;  // empty for the root
  std::string base;    // name of the base joint: a point of the parent (or the root origin)
  std::vector<PointSpec> points;
};

// What went wrong, and where: `segment` indexes the specs (-1: the model as a
// whole), `point` indexes that segment's points (-1: the segment itself) and
// `field` names the offending field ("name", "parent", "base", "points").
class ModelError : public std::invalid_argument {
 public:
  ModelError(int segment, int point, std::string field, const std::string& what)
      : std::invalid_argument(what), segment_(segment), point_(point), field_(std::move(field)) {}
  int segment() const { return segment_; }
  int point() const { return point_; }
  const std::string& field() const { return field_; }

 private:
  int segment_;
  int point_;
  std::string field_;
};

Model build_model(const std::string& name, const std::vector<SegmentSpec>& specs,
                  const Eigen::Vector3d& root_rest_m);

}  // namespace fabrik
