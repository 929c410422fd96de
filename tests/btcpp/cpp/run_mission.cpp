// Runs a mission exported by `hearth export` in BehaviorTree.CPP with Hearth's node types
// (hearth/executive/cpp/hearth_nodes.hpp) and a stand-in Say skill that prints what it says.
//   run_mission MISSION.xml [key=value ...]   (values set on the root blackboard first)
// Prints "say: TEXT" per Say tick and "status: SUCCESS|FAILURE" at the end.
#include "hearth_nodes.hpp"

#include <iostream>

int main(int argc, char** argv)
{
  if(argc < 2)
  {
    std::cerr << "usage: run_mission MISSION.xml [key=value ...]\n";
    return 2;
  }
  BT::BehaviorTreeFactory factory;
  hearth::registerNodes(factory);
  factory.registerSimpleAction(
      "Say",
      [](BT::TreeNode& node) {
        std::cout << "say: " << node.getInput<std::string>("text").value() << std::endl;
        return BT::NodeStatus::SUCCESS;
      },
      { BT::InputPort<std::string>("text"), BT::InputPort<BT::AnyTypeAllowed>("values"),
        BT::OutputPort<std::string>("said") });
  auto bb = BT::Blackboard::create();
  for(int i = 2; i < argc; ++i)
  {
    const std::string kv(argv[i]);
    const auto eq = kv.find('=');
    bb->set(kv.substr(0, eq), kv.substr(eq + 1));
  }
  auto tree = factory.createTreeFromFile(argv[1], bb);   // its main_tree_to_execute
  const auto status = tree.tickWhileRunning(std::chrono::milliseconds(1));
  std::cout << "status: " << BT::toStr(status) << std::endl;
  return 0;
}
