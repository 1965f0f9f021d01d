// The learned stepper in a build without LibTorch: everything that needs the network says so.
#include "core/Error.h"
#include "learning/nn/Corrector.h"
#include "learning/nn/Stepper.h"

namespace viscera::learning {

namespace {
[[noreturn]] void noTorch() {
  throw Error("this build of Viscera has no LibTorch (configured with VISCERA_WITH_TORCH=OFF or without libtorch-dev): "
              "learned components are not available");
}
}  // namespace

struct Stepper::Impl {};
struct Corrector::Impl {};

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

Corrector::Corrector(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}
Corrector::Corrector(const RestMesh&, const GridShape&, const Eigen::Vector3d&, const CorrectorArchitecture&, const std::string&,
                     std::uint64_t) {
  noTorch();
}
Corrector Corrector::load(const std::string&) { noTorch(); }
Corrector::~Corrector() = default;
Corrector::Corrector(Corrector&&) noexcept = default;
Corrector& Corrector::operator=(Corrector&&) noexcept = default;
void Corrector::checkMesh(const RestMesh&, const std::string&) const { noTorch(); }
void Corrector::save(const std::string&, const std::string&) const { noTorch(); }
Eigen::Matrix3Xd Corrector::correct(const Eigen::Matrix3Xd&, const InstrumentInput&) const { noTorch(); }
const std::vector<int>& Corrector::movableNodes() const { noTorch(); }
const RestMesh& Corrector::mesh() const { noTorch(); }
const GridShape& Corrector::grid() const { noTorch(); }
const CorrectorArchitecture& Corrector::architecture() const { noTorch(); }
const std::string& Corrector::units() const { noTorch(); }
const std::string& Corrector::training() const { noTorch(); }
std::int64_t Corrector::parameters() const { noTorch(); }
Eigen::Matrix3Xd Corrector::refinedSurface(const Eigen::Matrix3Xd&) const { noTorch(); }
void trainCorrector(const CorrectorTrainOptions&, const std::function<void(const CorrectorEpochReport&)>&) { noTorch(); }

}  // namespace viscera::learning
