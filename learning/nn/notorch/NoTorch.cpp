// The learned stepper in a build without LibTorch: everything that needs the network says so.
#include "core/Error.h"
#include "learning/nn/Stepper.h"

namespace viscera::learning {

namespace {
[[noreturn]] void noTorch() {
  throw Error("this build of Viscera has no LibTorch (configured with VISCERA_WITH_TORCH=OFF or without libtorch-dev): "
              "learned components are not available");
}
}  // namespace

struct Stepper::Impl {};

bool torchAvailable() { return false; }
void setTorchThreads(int) {}

Stepper::Stepper(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}
Stepper::Stepper(const RestMesh&, const StepperArchitecture&, const StepperNormalisers&, double, const std::string&,
                 std::uint64_t) {
  noTorch();
}
Stepper Stepper::load(const std::string&) { noTorch(); }
Stepper::~Stepper() = default;
Stepper::Stepper(Stepper&&) noexcept = default;
Stepper& Stepper::operator=(Stepper&&) noexcept = default;
void Stepper::checkMesh(const RestMesh&, const std::string&) const { noTorch(); }
void Stepper::save(const std::string&, const std::string&) const { noTorch(); }
Eigen::Matrix3Xd Stepper::step(const Eigen::Matrix3Xd&, const InstrumentInput&) const { noTorch(); }
const RestMesh& Stepper::mesh() const { noTorch(); }
const StepperArchitecture& Stepper::architecture() const { noTorch(); }
const StepperNormalisers& Stepper::normalisers() const { noTorch(); }
double Stepper::framePeriod() const { noTorch(); }
const std::string& Stepper::units() const { noTorch(); }
std::int64_t Stepper::parameters() const { noTorch(); }
const std::string& Stepper::training() const { noTorch(); }
GemmSpeed measureGemm(int, int, int, int) { noTorch(); }
void trainStepper(const StepperTrainOptions&, const std::function<void(const EpochReport&)>&) { noTorch(); }

}  // namespace viscera::learning
