// The VIO config YAML (config/vio_euroc.yaml): loading and the options' own check.
#include "fuzz/fuzz_target.h"
#include "optinav/vio/estimator.h"

using namespace optinav;

OPTINAV_FUZZ_TARGET(vio_config) {
  fuzz::QuietLibraries();
  const std::string path = fuzz::WriteScratch("vio.yaml", data, size);
  try {
    const vio::VioOptions o = vio::LoadVioOptions(path);
    (void)o.Check();
  } catch (const Error&) {
  }
  return 0;
}
