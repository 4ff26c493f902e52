// Stub of the ArduinoBLE API used by the sketch (signatures of ArduinoBLE 1.3):
// declarations only, for the compile check in `make test`.
#pragma once

#include <stdint.h>

enum BLEProperty : uint8_t {
  BLEBroadcast = 0x01, BLERead = 0x02, BLEWriteWithoutResponse = 0x04, BLEWrite = 0x08,
  BLENotify = 0x10, BLEIndicate = 0x20
};
enum BLECharacteristicEvent { BLESubscribed = 0, BLEUnsubscribed = 1, BLEWritten = 3 };
enum BLEDeviceEvent { BLEConnected = 0, BLEDisconnected = 1 };

class BLEDevice {
 public:
  bool connected() const;
};
class BLECharacteristic;
typedef void (*BLECharacteristicEventHandler)(BLEDevice device, BLECharacteristic characteristic);
typedef void (*BLEDeviceEventHandler)(BLEDevice device);

class BLECharacteristic {
 public:
  BLECharacteristic(const char* uuid, uint8_t properties, int valueSize, bool fixedLength = false);
  const uint8_t* value() const;
  int valueLength() const;
  int writeValue(const uint8_t value[], int length);
  void setEventHandler(int event, BLECharacteristicEventHandler eventHandler);
};

class BLEService {
 public:
  explicit BLEService(const char* uuid);
  void addCharacteristic(BLECharacteristic& characteristic);
};

class BLELocalDevice {
 public:
  int begin();
  void poll();
  void setLocalName(const char* localName);
  void setDeviceName(const char* deviceName);
  void setAdvertisedService(const BLEService& service);
  void addService(BLEService& service);
  void setConnectionInterval(uint16_t minimumConnectionInterval, uint16_t maximumConnectionInterval);
  int advertise();
  void setEventHandler(BLEDeviceEvent event, BLEDeviceEventHandler eventHandler);
};
extern BLELocalDevice& BLE;
