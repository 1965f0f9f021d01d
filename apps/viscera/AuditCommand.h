// `viscera audit`: see docs/user-guide.md, "Model audit".
#pragma once

#include <functional>

namespace CLI {
class App;
}

namespace viscera {

void addAuditCommand(CLI::App& app, std::function<int()>& action);

}  // namespace viscera
