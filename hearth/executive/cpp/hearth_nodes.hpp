// Hearth's node types for BehaviorTree.CPP v4, so that a mission written by
// `hearth export MISSION.yaml --format btcpp` runs in a BT.CPP application as it is.
//
//   #include "hearth_nodes.hpp"
//   BT::BehaviorTreeFactory factory;
//   hearth::registerNodes(factory);          // Check, Guard, Watch, ForEach, StateMachine,
//                                            // State, Succeed, Fail, SetValue, Wait
//   factory.registerNodeType<MyNavigateTo>("NavigateTo");   // your skills, as the
//   ...                                                      // <TreeNodesModel> declares them
//   auto tree = factory.createTreeFromFile("mission.xml");
//   tree.tickWhileRunning();
//
// Header only; C++17; BehaviorTree.CPP 4.x (checked against 4.8.4). The semantics are
// Hearth's (docs/missions.md, "Node kinds" and "From and to BehaviorTree.CPP"); the
// differences BT.CPP's own ticking brings are listed there.
//
// Values: Hearth's blackboard holds typed values; a BT.CPP blackboard holds what your
// nodes write. Conditions compare two values as numbers when both read as numbers, else
// as text (as BT.CPP's scripts do); a key that is not set makes a condition false.
// ForEach writes each item to its `as` key as text (a JSON item as its JSON text).
//
// Copyright the Hearth authors; the same licence as Hearth.
#pragma once

#include <behaviortree_cpp/action_node.h>
#include <behaviortree_cpp/bt_factory.h>
#include <behaviortree_cpp/condition_node.h>
#include <behaviortree_cpp/control_node.h>
#include <behaviortree_cpp/decorator_node.h>

#include <chrono>
#include <cstdlib>
#include <map>
#include <optional>
#include <sstream>
#include <string>
#include <vector>

namespace hearth
{

// ---------------------------------------------------------------------------------------
// Values and the condition language
// ---------------------------------------------------------------------------------------
namespace detail
{

inline std::string trim(const std::string& s)
{
  const auto b = s.find_first_not_of(" \t\r\n");
  if(b == std::string::npos)
    return "";
  const auto e = s.find_last_not_of(" \t\r\n");
  return s.substr(b, e - b + 1);
}

inline std::optional<double> asNumber(const std::string& text)
{
  const std::string t = trim(text);
  if(t.empty())
    return std::nullopt;
  char* end = nullptr;
  const double v = std::strtod(t.c_str(), &end);
  if(end != t.c_str() + t.size())
    return std::nullopt;
  return v;
}

/// A value a condition reads: unset, or text (numbers and booleans kept as their text).
struct Value
{
  bool set = false;
  std::string text;
  std::vector<std::string> items;   // a list ([a, b] literal or a vector entry)
  bool list = false;
};

inline std::string anyText(const BT::Any& any)
{
  if(any.empty())
    return "";
  if(any.isString())
    return any.cast<std::string>();
  if(any.isType<bool>())
    return any.cast<bool>() ? "true" : "false";
  if(any.isIntegral())
    return std::to_string(any.cast<int64_t>());
  if(any.isNumber())
  {
    std::ostringstream os;
    os << any.cast<double>();
    return os.str();
  }
  if(auto s = any.tryCast<std::string>())
    return s.value();
  return std::string("<") + BT::demangle(any.type()) + ">";
}

inline Value entry(const BT::Blackboard::Ptr& bb, const std::string& key)
{
  Value v;
  auto locked = bb->getAnyLocked(key);
  if(!locked || locked->empty())
    return v;
  v.set = true;
  if(auto vec = locked->tryCast<std::vector<std::string>>())
  {
    v.list = true;
    v.items = vec.value();
    return v;
  }
  v.text = anyText(*locked.get());
  return v;
}

/// Split "a, 'b', 3" (the inside of a [list] literal) into items.
inline std::vector<std::string> listItems(const std::string& inner)
{
  std::vector<std::string> out;
  std::string cur;
  char quote = 0;
  for(char c : inner)
  {
    if(quote)
    {
      if(c == quote)
        quote = 0;
      else
        cur += c;
    }
    else if(c == '\'' || c == '"')
      quote = c;
    else if(c == ',')
    {
      out.push_back(trim(cur));
      cur.clear();
    }
    else
      cur += c;
  }
  if(!trim(cur).empty() || !out.empty())
    out.push_back(trim(cur));
  return out;
}

/// An operand: {key} (the tree's ports are keys in BT.CPP), or a YAML-like literal.
inline Value operand(const BT::Blackboard::Ptr& bb, const std::string& token)
{
  const std::string t = trim(token);
  if(t.size() >= 3 && t.front() == '{' && t.back() == '}')
    return entry(bb, t.substr(1, t.size() - 2));
  if(t.size() >= 2 && t.front() == '$')
    return entry(bb, t.substr(1));
  Value v;
  v.set = true;
  if(t.size() >= 2 && (t.front() == '\'' || t.front() == '"') && t.back() == t.front())
    v.text = t.substr(1, t.size() - 2);
  else if(t.size() >= 2 && t.front() == '[' && t.back() == ']')
  {
    v.list = true;
    v.items = listItems(t.substr(1, t.size() - 2));
  }
  else if(t == "True")
    v.text = "true";
  else if(t == "False")
    v.text = "false";
  else
    v.text = t;
  return v;
}

inline bool truthy(const Value& v)
{
  if(!v.set)
    return false;
  if(v.list)
    return !v.items.empty();
  if(auto n = asNumber(v.text))
    return *n != 0.0;
  return !v.text.empty() && v.text != "false" && v.text != "null";
}

inline bool equal(const std::string& a, const std::string& b)
{
  auto x = asNumber(a), y = asNumber(b);
  if(x && y)
    return *x == *y;
  return a == b;
}

/// The tokens of one simple condition: [not] operand [op operand].
inline std::vector<std::string> tokens(const std::string& text)
{
  std::vector<std::string> out;
  size_t i = 0;
  const size_t n = text.size();
  while(i < n)
  {
    const char c = text[i];
    if(c == ' ' || c == '\t')
    {
      ++i;
      continue;
    }
    size_t j = i;
    if(c == '\'' || c == '"')
    {
      j = text.find(c, i + 1);
      j = (j == std::string::npos) ? n : j + 1;
    }
    else if(c == '[')
    {
      j = text.find(']', i);
      j = (j == std::string::npos) ? n : j + 1;
    }
    else if(c == '=' || c == '!' || c == '<' || c == '>')
    {
      j = i + 1;
      if(j < n && text[j] == '=')
        ++j;
    }
    else
    {
      while(j < n && text[j] != ' ' && text[j] != '\t' && text[j] != '=' &&
            text[j] != '!' && text[j] != '<' && text[j] != '>' && text[j] != '\'' &&
            text[j] != '"')
        ++j;
    }
    out.push_back(text.substr(i, j - i));
    i = j;
  }
  // "not in" is one operator
  for(size_t k = 0; k + 1 < out.size(); ++k)
  {
    if(out[k] == "not" && out[k + 1] == "in" && k > 0)
    {
      out[k] = "not in";
      out.erase(out.begin() + static_cast<long>(k) + 1);
    }
  }
  return out;
}

inline bool simple(const BT::Blackboard::Ptr& bb, const std::string& text)
{
  const auto t = tokens(text);
  if(t.empty())
    throw BT::RuntimeError("Check: empty condition");
  if(t.size() == 1)
    return truthy(operand(bb, t[0]));
  if(t.size() == 2 && t[0] == "not")
  {
    const Value v = operand(bb, t[1]);
    return v.set && !truthy(v);   // an unset key makes any condition false, as in Hearth
  }
  if(t.size() != 3)
    throw BT::RuntimeError("Check: cannot read condition '", text, "'");
  const Value a = operand(bb, t[0]);
  const Value b = operand(bb, t[2]);
  if(!a.set || !b.set)
    return false;
  const std::string& op = t[1];
  if(op == "in" || op == "not in")
  {
    bool found = false;
    if(b.list)
    {
      for(const auto& item : b.items)
        found = found || equal(a.text, item);
    }
    else
      found = b.text.find(a.text) != std::string::npos;
    return op == "in" ? found : !found;
  }
  if(op == "==")
    return equal(a.text, b.text);
  if(op == "!=")
    return !equal(a.text, b.text);
  auto x = asNumber(a.text), y = asNumber(b.text);
  if(!x || !y)
    return false;   // Hearth: < <= > >= compare numbers only
  if(op == "<")
    return *x < *y;
  if(op == "<=")
    return *x <= *y;
  if(op == ">")
    return *x > *y;
  if(op == ">=")
    return *x >= *y;
  throw BT::RuntimeError("Check: unknown operator '", op, "' in '", text, "'");
}

/// A Hearth condition: simple conditions joined by && and || (&& binds tighter).
inline bool evaluate(const BT::Blackboard::Ptr& bb, const std::string& text)
{
  // Cut at && and || outside quotes.
  std::vector<std::vector<std::string>> groups(1);
  std::string cur;
  char quote = 0;
  for(size_t i = 0; i < text.size(); ++i)
  {
    const char c = text[i];
    if(quote)
    {
      if(c == quote)
        quote = 0;
      cur += c;
      continue;
    }
    if(c == '\'' || c == '"')
    {
      quote = c;
      cur += c;
      continue;
    }
    if(i + 1 < text.size() && ((c == '&' && text[i + 1] == '&') ||
                               (c == '|' && text[i + 1] == '|')))
    {
      groups.back().push_back(cur);
      cur.clear();
      if(c == '|')
        groups.emplace_back();
      ++i;
      continue;
    }
    cur += c;
  }
  groups.back().push_back(cur);
  for(const auto& group : groups)
  {
    bool all = true;
    for(const auto& part : group)
    {
      if(!simple(bb, part))
      {
        all = false;
        break;
      }
    }
    if(all)
      return true;
  }
  return false;
}

/// "a:b;c:d" or json:{"a": "b"} -> map
inline std::map<std::string, std::string> pairs(const std::string& text)
{
  std::map<std::string, std::string> out;
  std::string t = trim(text);
  if(t.rfind("json:", 0) == 0)
  {
    // {"k": "v", ...}: flat string pairs, which is all export writes here.
    t = t.substr(5);
    std::vector<std::string> strings;
    for(size_t i = 0; i < t.size(); ++i)
    {
      if(t[i] != '"')
        continue;
      std::string s;
      for(++i; i < t.size() && t[i] != '"'; ++i)
      {
        if(t[i] == '\\' && i + 1 < t.size())
          ++i;
        s += t[i];
      }
      strings.push_back(s);
    }
    for(size_t i = 0; i + 1 < strings.size(); i += 2)
      out[strings[i]] = strings[i + 1];
    return out;
  }
  std::stringstream ss(t);
  std::string part;
  while(std::getline(ss, part, ';'))
  {
    const auto colon = part.find(':');
    if(colon == std::string::npos)
      continue;
    out[trim(part.substr(0, colon))] = trim(part.substr(colon + 1));
  }
  return out;
}

/// The items of a json: list literal: scalars as their text, anything else as JSON text.
inline std::vector<std::string> jsonItems(const std::string& json)
{
  std::vector<std::string> out;
  std::string t = trim(json);
  if(t.size() < 2 || t.front() != '[' || t.back() != ']')
    throw BT::RuntimeError("ForEach: expected a JSON list, got ", t);
  int depth = 0;
  bool in_string = false;
  std::string cur;
  for(size_t i = 1; i + 1 < t.size(); ++i)
  {
    const char c = t[i];
    if(in_string)
    {
      cur += c;
      if(c == '\\' && i + 2 < t.size())
        cur += t[++i];
      else if(c == '"')
        in_string = false;
      continue;
    }
    if(c == '"')
      in_string = true;
    else if(c == '[' || c == '{')
      ++depth;
    else if(c == ']' || c == '}')
      --depth;
    else if(c == ',' && depth == 0)
    {
      out.push_back(trim(cur));
      cur.clear();
      continue;
    }
    cur += c;
  }
  if(!trim(cur).empty())
    out.push_back(trim(cur));
  for(auto& item : out)
  {
    if(item.size() >= 2 && item.front() == '"' && item.back() == '"')
      item = item.substr(1, item.size() - 2);
  }
  return out;
}

}  // namespace detail

// ---------------------------------------------------------------------------------------
// Leaves
// ---------------------------------------------------------------------------------------
/// Hearth's `condition`: success when the expression holds, failure otherwise.
class Check : public BT::ConditionNode
{
public:
  Check(const std::string& name, const BT::NodeConfig& config) : ConditionNode(name, config)
  {}
  static BT::PortsList providedPorts()
  {
    // AnyTypeAllowed: expr="{docked}" is a condition, and BT.CPP must not type the entry.
    return { BT::InputPort<BT::AnyTypeAllowed>("expr", "a Hearth condition") };
  }
  BT::NodeStatus tick() override
  {
    // The raw attribute: its {key}s are the condition's operands, not one port pointer.
    const std::string expr(getRawPortValue("expr"));
    return detail::evaluate(config().blackboard, expr) ? BT::NodeStatus::SUCCESS :
                                                         BT::NodeStatus::FAILURE;
  }
};

/// Hearth's `succeed` / `fail` with a message.
template <BT::NodeStatus Result>
class Message : public BT::SyncActionNode
{
public:
  Message(const std::string& name, const BT::NodeConfig& config)
    : SyncActionNode(name, config)
  {}
  static BT::PortsList providedPorts()
  {
    return { BT::InputPort<std::string>("message", "", "feedback message") };
  }
  BT::NodeStatus tick() override
  {
    return Result;
  }
};
using Succeed = Message<BT::NodeStatus::SUCCESS>;
using Fail = Message<BT::NodeStatus::FAILURE>;

/// Hearth's SetValue skill: write `value` (a literal, or another entry's value) to `output`.
class SetValue : public BT::SyncActionNode
{
public:
  SetValue(const std::string& name, const BT::NodeConfig& config)
    : SyncActionNode(name, config)
  {}
  static BT::PortsList providedPorts()
  {
    return { BT::InputPort<BT::AnyTypeAllowed>("value"),
             BT::OutputPort<BT::AnyTypeAllowed>("output") };
  }
  BT::NodeStatus tick() override
  {
    // value is optional (Hearth's default: nothing, written here as empty text)
    const std::string raw =
        config().input_ports.count("value") ? std::string(getRawPortValue("value")) : "";
    const std::string out(getRawPortValue("output"));
    if(!isBlackboardPointer(out))
      throw BT::RuntimeError("SetValue: output must be a {key}");
    const std::string target(stripBlackboardPointer(out));
    auto bb = config().blackboard;
    if(isBlackboardPointer(raw))
    {
      auto src = bb->getEntry(std::string(stripBlackboardPointer(raw)));
      if(!src)
        throw BT::RuntimeError("SetValue: ", raw, " is not set");
      BT::Any copy;
      {
        std::scoped_lock lk(src->entry_mutex);
        copy = src->value;
      }
      bb->set(target, copy);
    }
    else
    {
      std::string text = raw;
      if(text.rfind("json:", 0) == 0)
        text = detail::trim(text.substr(5));
      if(text.size() >= 2 && text.front() == '"' && text.back() == '"')
        bb->set(target, text.substr(1, text.size() - 2));
      else if(auto n = detail::asNumber(text))
        bb->set(target, *n);
      else if(text == "true" || text == "false")
        bb->set(target, text == "true");
      else
        bb->set(target, text);
    }
    return BT::NodeStatus::SUCCESS;
  }
};

/// Hearth's Wait skill: `seconds` of steady-clock time, then success.
class Wait : public BT::StatefulActionNode
{
public:
  Wait(const std::string& name, const BT::NodeConfig& config)
    : StatefulActionNode(name, config)
  {}
  static BT::PortsList providedPorts()
  {
    return { BT::InputPort<double>("seconds", "how long, in seconds") };
  }
  BT::NodeStatus onStart() override
  {
    const double s = getInput<double>("seconds").value_or(0.0);
    until_ = std::chrono::steady_clock::now() +
             std::chrono::duration_cast<std::chrono::steady_clock::duration>(
                 std::chrono::duration<double>(s));
    return onRunning();
  }
  BT::NodeStatus onRunning() override
  {
    return std::chrono::steady_clock::now() >= until_ ? BT::NodeStatus::SUCCESS :
                                                        BT::NodeStatus::RUNNING;
  }
  void onHalted() override
  {}

private:
  std::chrono::steady_clock::time_point until_;
};

// ---------------------------------------------------------------------------------------
// Decorators
// ---------------------------------------------------------------------------------------
/// Hearth's `guard`: tick the child while the condition holds, checked every tick; when it
/// stops holding, halt the child and fail.
class Guard : public BT::DecoratorNode
{
public:
  Guard(const std::string& name, const BT::NodeConfig& config) : DecoratorNode(name, config)
  {}
  static BT::PortsList providedPorts()
  {
    return { BT::InputPort<BT::AnyTypeAllowed>("while", "a Hearth condition") };
  }
  BT::NodeStatus tick() override
  {
    const std::string expr(getRawPortValue("while"));
    if(!detail::evaluate(config().blackboard, expr))
    {
      haltChild();
      return BT::NodeStatus::FAILURE;
    }
    setStatus(BT::NodeStatus::RUNNING);
    const auto st = child_node_->executeTick();
    if(BT::isStatusCompleted(st))
      resetChild();
    return st;
  }
};

/// Hearth's `watch`: when a watched runtime parameter (an entry of the tree) changes, halt
/// the child and start it again so that it reads the new value.
class Watch : public BT::DecoratorNode
{
public:
  Watch(const std::string& name, const BT::NodeConfig& config) : DecoratorNode(name, config)
  {}
  static BT::PortsList providedPorts()
  {
    return { BT::InputPort<std::string>("params", "entries to watch, ';'-separated") };
  }
  BT::NodeStatus tick() override
  {
    const auto now = snapshot();
    if(status() == BT::NodeStatus::RUNNING && now != seen_)
      haltChild();   // restart below with the new values
    seen_ = now;
    setStatus(BT::NodeStatus::RUNNING);
    const auto st = child_node_->executeTick();
    if(BT::isStatusCompleted(st))
      resetChild();
    return st;
  }

private:
  std::vector<std::string> snapshot()
  {
    std::vector<std::string> out;
    std::stringstream ss(std::string(getRawPortValue("params")));
    std::string name;
    while(std::getline(ss, name, ';'))
    {
      const auto v = detail::entry(config().blackboard, detail::trim(name));
      out.push_back(v.set ? v.text : std::string("\x01unset"));
    }
    return out;
  }
  std::vector<std::string> seen_;
};

/// Hearth's `for_each`: write each item to `as` and run the child once per item.
/// until="failure": success when every item succeeded, failure at the first failure;
/// until="success": success at the first success, failure when all failed.
class ForEach : public BT::DecoratorNode
{
public:
  ForEach(const std::string& name, const BT::NodeConfig& config)
    : DecoratorNode(name, config)
  {}
  static BT::PortsList providedPorts()
  {
    return { BT::InputPort<BT::AnyTypeAllowed>("in", "the items"),
             BT::OutputPort<BT::AnyTypeAllowed>("as", "the key each item is written to"),
             BT::InputPort<std::string>("until", "failure", "failure or success") };
  }
  BT::NodeStatus tick() override
  {
    const bool until_success = getInput<std::string>("until").value_or("failure") == "success";
    const auto stop_on = until_success ? BT::NodeStatus::SUCCESS : BT::NodeStatus::FAILURE;
    const auto go_on = until_success ? BT::NodeStatus::FAILURE : BT::NodeStatus::SUCCESS;
    if(status() != BT::NodeStatus::RUNNING)
    {
      items_ = read();
      index_ = 0;
      if(items_.empty())
        return go_on;
      write(items_[0]);
    }
    setStatus(BT::NodeStatus::RUNNING);
    const auto st = child_node_->executeTick();
    if(st == BT::NodeStatus::RUNNING)
      return st;
    resetChild();
    if(st == stop_on)
      return stop_on;
    if(++index_ >= items_.size())
      return go_on;
    write(items_[index_]);
    return BT::NodeStatus::RUNNING;   // one item per tick, as Hearth does
  }
  void halt() override
  {
    index_ = 0;
    DecoratorNode::halt();
  }

private:
  void write(const std::string& item)
  {
    const std::string out(getRawPortValue("as"));
    config().blackboard->set(std::string(stripBlackboardPointer(out)), item);
  }
  std::vector<std::string> read()
  {
    const std::string raw(getRawPortValue("in"));
    if(isBlackboardPointer(raw))
    {
      const auto v = detail::entry(config().blackboard, std::string(stripBlackboardPointer(raw)));
      if(!v.set)
        throw BT::RuntimeError("ForEach: ", raw, " is not set");
      if(v.list)
        return v.items;
      if(v.text.rfind("json:", 0) == 0)
        return detail::jsonItems(v.text.substr(5));
      if(!v.text.empty() && v.text.front() == '[')
        return detail::jsonItems(v.text);
      return split(v.text);
    }
    if(raw.rfind("json:", 0) == 0)
      return detail::jsonItems(raw.substr(5));
    return split(raw);
  }
  static std::vector<std::string> split(const std::string& text)
  {
    std::vector<std::string> out;
    for(const auto& part : BT::splitString(text, ';'))
      out.emplace_back(detail::trim(std::string(part)));
    return out;
  }
  std::vector<std::string> items_;
  size_t index_ = 0;
};

/// A state of a StateMachine: ticks its child; its ports are read by the machine.
class State : public BT::DecoratorNode
{
public:
  State(const std::string& name, const BT::NodeConfig& config) : DecoratorNode(name, config)
  {}
  static BT::PortsList providedPorts()
  {
    return { BT::InputPort<std::string>("transitions", "outcome:target pairs"),
             BT::InputPort<BT::AnyTypeAllowed>("outcome",
                                               "after a success, this {key}'s value") };
  }
  BT::NodeStatus tick() override
  {
    setStatus(BT::NodeStatus::RUNNING);
    const auto st = child_node_->executeTick();
    if(BT::isStatusCompleted(st))
      resetChild();
    return st;
  }
  /// The outcome after ``st``: success/failure, or the outcome key's value after a success.
  std::string outcome(BT::NodeStatus st)
  {
    if(st == BT::NodeStatus::FAILURE)
      return "failure";
    if(config().input_ports.count("outcome") == 0)   // optional: not in the XML
      return "success";
    const std::string raw(getRawPortValue("outcome"));
    if(isBlackboardPointer(raw))
    {
      const auto v = detail::entry(config().blackboard, std::string(stripBlackboardPointer(raw)));
      if(v.set)
        return v.text;
    }
    return "success";
  }
  std::map<std::string, std::string> transitions()
  {
    return detail::pairs(std::string(getRawPortValue("transitions")));
  }
};

// ---------------------------------------------------------------------------------------
// Control
// ---------------------------------------------------------------------------------------
/// Hearth's `state_machine` (SMACH semantics): states are <State name="..."> children; a
/// state's outcome picks the next state or a container outcome, which ends the machine
/// with the status `outcomes` maps it to. States that finish at once chain within one tick
/// (at most one pass over all states).
class StateMachine : public BT::ControlNode
{
public:
  StateMachine(const std::string& name, const BT::NodeConfig& config)
    : ControlNode(name, config)
  {}
  static BT::PortsList providedPorts()
  {
    return { BT::InputPort<std::string>("initial", "the first state"),
             BT::InputPort<std::string>("outcomes", "outcome:status pairs") };
  }
  BT::NodeStatus tick() override
  {
    if(status() != BT::NodeStatus::RUNNING)
      current_ = index(std::string(getRawPortValue("initial")));
    setStatus(BT::NodeStatus::RUNNING);
    const auto outcomes = detail::pairs(std::string(getRawPortValue("outcomes")));
    for(size_t step = 0; step <= children_nodes_.size(); ++step)
    {
      auto* state = dynamic_cast<State*>(children_nodes_[current_]);
      const auto st = children_nodes_[current_]->executeTick();
      if(st == BT::NodeStatus::RUNNING)
        return st;
      const std::string outcome = state->outcome(st);
      haltChild(current_);   // back to IDLE: a state entered again starts afresh
      const auto table = state->transitions();
      const auto it = table.find(outcome);
      if(it == table.end())
        return BT::NodeStatus::FAILURE;   // "unmapped outcome", as Hearth fails the block
      const auto done = outcomes.find(it->second);
      if(done != outcomes.end())
        return done->second == "success" ? BT::NodeStatus::SUCCESS : BT::NodeStatus::FAILURE;
      current_ = index(it->second);
    }
    return BT::NodeStatus::RUNNING;   // yield: the next tick goes on
  }
  void halt() override
  {
    current_ = 0;
    ControlNode::halt();
  }

private:
  size_t index(const std::string& name)
  {
    for(size_t i = 0; i < children_nodes_.size(); ++i)
    {
      if(children_nodes_[i]->name() == name)
        return i;
    }
    throw BT::RuntimeError("StateMachine ", this->name(), ": no state '", name, "'");
  }
  size_t current_ = 0;
};

/// Register every Hearth node type (those `hearth export` writes in <TreeNodesModel>, and
/// the generic SetValue and Wait skills).
inline void registerNodes(BT::BehaviorTreeFactory& factory)
{
  factory.registerNodeType<Check>("Check");
  factory.registerNodeType<Succeed>("Succeed");
  factory.registerNodeType<Fail>("Fail");
  factory.registerNodeType<SetValue>("SetValue");
  factory.registerNodeType<Wait>("Wait");
  factory.registerNodeType<Guard>("Guard");
  factory.registerNodeType<Watch>("Watch");
  factory.registerNodeType<ForEach>("ForEach");
  factory.registerNodeType<State>("State");
  factory.registerNodeType<StateMachine>("StateMachine");
}

}  // namespace hearth
