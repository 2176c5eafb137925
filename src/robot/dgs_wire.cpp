#include <dcl/robot/dgs_wire.hpp>

namespace dcl::robot {
namespace {

using backend::DgsStage;
using comm::OptimisationStage;

OptimisationStage toWire(DgsStage stage) {
  switch (stage) {
    case DgsStage::idle:
      return OptimisationStage::idle;
    case DgsStage::rotation:
      return OptimisationStage::rotation;
    case DgsStage::pose:
      return OptimisationStage::pose;
    case DgsStage::done:
      return OptimisationStage::done;
  }
  return OptimisationStage::idle;
}

DgsStage fromWire(OptimisationStage stage) {
  switch (stage) {
    case OptimisationStage::rotation:
      return DgsStage::rotation;
    case OptimisationStage::pose:
      return DgsStage::pose;
    case OptimisationStage::done:
      return DgsStage::done;
    default:
      return DgsStage::idle;
  }
}

comm::DgsState stateOf(const backend::DgsMessage& m) {
  comm::DgsState s;
  s.round = m.round;
  s.stage = toWire(m.stage);
  s.iteration = static_cast<std::uint32_t>(std::max(m.iteration, 0));
  s.initialised = m.initialised;
  s.converged = m.converged;
  for (const auto& [robot, p] : m.progress)
    s.progress.push_back({robot, p.iteration, p.converged_since, p.finished});
  return s;
}

void setState(backend::DgsMessage& out, const comm::DgsState& s) {
  out.stage = fromWire(s.stage);
  out.round = s.round;
  out.iteration = static_cast<int>(s.iteration);
  out.initialised = s.initialised;
  out.converged = s.converged;
  for (const comm::MemberProgress& p : s.progress)
    out.progress[p.robot] = {p.iteration, p.converged_since, p.finished};
}

}  // namespace

comm::Body toWire(const backend::DgsMessage& m) {
  if (!m.rotations.empty()) {
    comm::RotationEstimates r{stateOf(m), {}};
    for (const auto& [key, R] : m.rotations) r.rotations.emplace_back(key.keyframe, R);
    return r;
  }
  if (!m.poses.empty()) {
    comm::PoseEstimates p{stateOf(m), {}, false, false};
    for (const auto& [key, T] : m.poses) p.poses.emplace_back(key.keyframe, T);
    return p;
  }
  return stateOf(m);
}

std::optional<backend::DgsMessage> fromWire(const comm::Message& message) {
  backend::DgsMessage out;
  out.from = message.header.sender;
  if (!message.header.receiver) return std::nullopt;  // DGS messages are addressed
  out.to = *message.header.receiver;
  if (const auto* s = std::get_if<comm::DgsState>(&message.body)) {
    if (s->stage == OptimisationStage::idle || s->stage == OptimisationStage::refine)
      return std::nullopt;
    setState(out, *s);
  } else if (const auto* r = std::get_if<comm::RotationEstimates>(&message.body)) {
    setState(out, r->state);
    for (const auto& [id, R] : r->rotations) out.rotations[{out.from, id}] = R;
  } else if (const auto* p = std::get_if<comm::PoseEstimates>(&message.body)) {
    if (p->state.stage == OptimisationStage::refine) return std::nullopt;
    setState(out, p->state);
    for (const auto& [id, T] : p->poses) out.poses[{out.from, id}] = T;
  } else {
    return std::nullopt;
  }
  return out;
}

RoundOrigin roundOrigin(const comm::Message& message) {
  const comm::DgsState* state = nullptr;
  if (const auto* s = std::get_if<comm::DgsState>(&message.body)) state = s;
  if (const auto* r = std::get_if<comm::RotationEstimates>(&message.body)) state = &r->state;
  if (const auto* p = std::get_if<comm::PoseEstimates>(&message.body)) state = &p->state;
  if (state == nullptr) return {};
  return {state->frame, state->warm};
}

comm::Body toWire(const RefineMessage& m) {
  comm::DgsState state;
  state.round = m.round;
  state.stage = OptimisationStage::refine;
  state.iteration = m.step;
  if (m.cost_share) {
    state.change = *m.cost_share;
    state.converged = m.finished;
    return state;
  }
  comm::PoseEstimates p{state, {}, !m.increments, m.increments};
  for (const auto& [key, T] : m.poses) p.poses.emplace_back(key.keyframe, T);
  return p;
}

std::optional<RefineMessage> refineFromWire(const comm::Message& message) {
  RefineMessage out;
  out.from = message.header.sender;
  out.to = message.header.receiver;
  if (const auto* s = std::get_if<comm::DgsState>(&message.body)) {
    if (s->stage != OptimisationStage::refine) return std::nullopt;
    out.round = s->round;
    out.step = s->iteration;
    out.cost_share = s->change;
    out.finished = s->converged;
    return out;
  }
  if (const auto* p = std::get_if<comm::PoseEstimates>(&message.body)) {
    // Separators are addressed: they are the receiver's loops' ends.
    if (p->state.stage != OptimisationStage::refine || !out.to) return std::nullopt;
    out.round = p->state.round;
    out.step = p->state.iteration;
    out.increments = p->increments;
    for (const auto& [id, T] : p->poses) out.poses[{out.from, id}] = T;
    return out;
  }
  return std::nullopt;
}

}  // namespace dcl::robot
