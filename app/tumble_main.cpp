// The `tumble` program: the engine's command line with the built-in systems registered and the viewer.

#include "app/cli.h"
#include "app/viewer.h"
#include "systems/builtin.h"

int main(int argc, char** argv) {
    tumble::Catalog catalog;
    tumble::registerBuiltinSystems(catalog);
    return tumble::runCli(argc, argv, catalog, tumble::runViewer);
}
