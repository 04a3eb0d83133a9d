// sandswim: wiring only. The real streams, environment, clock, REST client and engine probe go
// into the Environment; cli/commands.cc does the rest.
#include <signal.h>
#include <unistd.h>

#include <cstdlib>
#include <iostream>

#include "cli/client.h"
#include "cli/commands.h"
#include "platform/clock.h"
#include "platform/engine_probe.h"

int main(int argc, char** argv) {
  signal(SIGPIPE, SIG_IGN);  // `sandswim results 12 | head` ends quietly
  sandswim::cli::Environment env;
  env.out = &std::cout;
  env.err = &std::cerr;
  env.in = &std::cin;
  env.out_is_tty = isatty(STDOUT_FILENO) == 1;
  env.err_is_tty = isatty(STDERR_FILENO) == 1;
  env.getenv = [](const char* name) { return static_cast<const char*>(std::getenv(name)); };
  sandswim::SystemClock clock;
  env.clock = &clock;
  env.make_client = [](const sandswim::ClientOptions& o) { return sandswim::cli::NewDaemonClient(o); };
  env.probe_engine = [] { return sandswim::ProbeEngineVersion(); };
  return sandswim::cli::RunCli(argc, argv, env);
}
