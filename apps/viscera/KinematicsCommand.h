// `viscera kinematics fk|ik`: converts between PSM joint logs (t,q1..q6) and Cartesian tool-tip
// trajectories (t,x,y,z,qx,qy,qz,qw) through the PSM's kinematics and a registration transform.
#pragma once

#include <functional>

namespace CLI {
class App;
}

namespace viscera {

// Adds the `kinematics` subcommand (with `fk` and `ik`) to `app`; see TrajectoryCommand.h for the
// `action` protocol.
void addKinematicsCommand(CLI::App& app, std::function<int()>& action);

}  // namespace viscera
