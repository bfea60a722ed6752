// Random identifiers for meshes, sessions and jobs: 128 bits from the OS, hex, with a prefix.
#ifndef ACTOPO_SERVER_SERVICE_IDS_H_
#define ACTOPO_SERVER_SERVICE_IDS_H_

#include <string>

namespace actopo::service {

// e.g. NewId("s") == "s-3f9c0e...": unguessable, so a session id is a capability.
std::string NewId(const std::string& prefix);

}  // namespace actopo::service

#endif  // ACTOPO_SERVER_SERVICE_IDS_H_
