// sandswim-render: draws one plot for sandswimd in a process of its own (server/analysis/plot_renderer.h).
#include "server/analysis/plot_renderer.h"

int main(int argc, char** argv) { return sandswim::RenderMain(argc, argv); }
