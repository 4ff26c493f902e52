// Stub of ArduinoBLE's utility/ATT.h (the part the sketch uses: the negotiated MTU
// per connection handle), with the signatures of ArduinoBLE 1.3: compile check only.
#pragma once

#include <stdint.h>

class ATTClass {
 public:
  virtual bool connected(uint16_t handle) const;
  virtual uint16_t mtu(uint16_t handle) const;
};
extern ATTClass& ATT;
