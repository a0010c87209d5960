// valve_relay: the launcher valve's relay board (protocol RVR1) for an Arduino Uno or Nano (ATmega328P).
//
// The board, not the computer, is the safety device: it times every pulse itself (capped at MAX_PULSE_MS),
// drops the relay and disarms when no command arrives for KEEPALIVE_TIMEOUT_MS while armed (hold-to-run), and
// latches a pressed e-stop button until CLEAR with the button released. The relay is off at reset and power-up,
// and the hardware watchdog resets the board if this loop ever hangs.
//
// The state machine mirrors rollability_ros/core/rig/relay_protocol.py (RelayDevice) line for line; the relay
// simulator runs that Python class. Change both together, and the limits in both (the computer reads them from
// the HELLO answer). Wiring, flashing and the protocol table: docs/firmware.md.

#include <avr/wdt.h>

// ---- configuration (keep in step with relay_protocol.DEFAULT_*) ----
const unsigned long MAX_PULSE_MS = 500;          // longest relay-on time of one pulse, ms
const unsigned long KEEPALIVE_TIMEOUT_MS = 250;  // armed silence that drops the relay and disarms, ms
const uint8_t RELAY_PIN = 7;        // to the relay module's IN (or a logic-level MOSFET driving the relay coil)
const bool RELAY_ACTIVE_HIGH = true; // false for the common active-low relay modules (IN low = coil on)
const uint8_t ESTOP_PIN = 2;        // normally-closed e-stop contact between this pin and GND (INPUT_PULLUP):
                                    // pressed or a broken wire reads HIGH = e-stop
const uint8_t LED_PIN = LED_BUILTIN; // lit while armed
const uint8_t MAX_LINE = 32;

// ---- state (names as in RelayDevice) ----
bool armed = false;
bool relayOn = false;
const char *fault = "none";          // "none" | "estop" | "keepalive"
bool estopHeld = false;
unsigned long pulseStartMs = 0;
unsigned long pulseLengthMs = 0;
unsigned long lastCommandMs = 0;
char line[MAX_LINE + 1];
uint8_t lineLength = 0;
bool lineTooLong = false;

void writeRelay(bool on) {
  relayOn = on;
  digitalWrite(RELAY_PIN, (on == RELAY_ACTIVE_HIGH) ? HIGH : LOW);
}

void trip(const char *why) {
  armed = false;
  fault = why;
  writeRelay(false);
}

// The periodic checks: pulse end, keep-alive, e-stop input (RelayDevice.tick). millis() differences are
// rollover-safe as unsigned arithmetic.
void tick() {
  unsigned long now = millis();
  estopHeld = digitalRead(ESTOP_PIN) == HIGH;
  if (estopHeld && (armed || relayOn || strcmp(fault, "estop") != 0)) trip("estop");
  if (relayOn && now - pulseStartMs >= pulseLengthMs) writeRelay(false);
  if (armed && now - lastCommandMs >= KEEPALIVE_TIMEOUT_MS) trip("keepalive");
  digitalWrite(LED_PIN, armed ? HIGH : LOW);
}

void printState(const char *prefix) {
  Serial.print(prefix);
  Serial.print(F("armed="));
  Serial.print(armed ? 1 : 0);
  Serial.print(F(" relay="));
  Serial.print(relayOn ? 1 : 0);
  Serial.print(F(" fault="));
  Serial.println(fault);
}

bool allDigits(const char *text) {
  if (*text == '\0') return false;
  for (; *text; ++text) if (*text < '0' || *text > '9') return false;
  return true;
}

// One received line (RelayDevice.handle). Every answer is one line.
void handle(char *text) {
  tick();
  char *command = strtok(text, " ");
  char *argument = strtok(NULL, " ");
  char *extra = strtok(NULL, " ");
  if (command == NULL) { Serial.println(F("ERR BAD_ARG")); return; }
  bool isPulse = strcmp(command, "PULSE") == 0;
  bool known = isPulse || !strcmp(command, "HELLO") || !strcmp(command, "ARM") || !strcmp(command, "KA") ||
               !strcmp(command, "STATUS") || !strcmp(command, "OFF") || !strcmp(command, "DISARM") ||
               !strcmp(command, "CLEAR");
  if (!known || (argument != NULL && !isPulse)) { Serial.println(F("ERR UNKNOWN")); return; }
  unsigned long requested = 0;
  if (isPulse) {
    if (argument == NULL || extra != NULL || !allDigits(argument) || strlen(argument) > 9) {
      Serial.println(F("ERR BAD_ARG")); return;
    }
    requested = strtoul(argument, NULL, 10);
    if (requested == 0) { Serial.println(F("ERR BAD_ARG")); return; }
  }
  unsigned long now = millis();
  lastCommandMs = now;  // any well-formed command is a keep-alive
  if (!strcmp(command, "HELLO")) {
    Serial.print(F("OK HELLO RVR1 max_pulse_ms="));
    Serial.print(MAX_PULSE_MS);
    Serial.print(F(" keepalive_timeout_ms="));
    Serial.println(KEEPALIVE_TIMEOUT_MS);
  } else if (!strcmp(command, "KA")) {
    printState("OK KA ");
  } else if (!strcmp(command, "STATUS")) {
    printState("OK STATUS ");
  } else if (!strcmp(command, "OFF")) {
    writeRelay(false);
    Serial.println(F("OK OFF"));
  } else if (!strcmp(command, "DISARM")) {
    armed = false;
    writeRelay(false);
    Serial.println(F("OK DISARMED"));
  } else if (!strcmp(command, "CLEAR")) {
    if (estopHeld) { Serial.println(F("ERR ESTOP_HELD")); return; }
    fault = "none";
    Serial.println(F("OK CLEARED"));
  } else if (!strcmp(command, "ARM")) {
    if (!strcmp(fault, "estop")) { Serial.println(F("ERR ESTOP")); return; }
    armed = true;
    fault = "none";
    Serial.println(F("OK ARMED"));
  } else {  // PULSE
    if (!armed) { Serial.println(F("ERR NOT_ARMED")); return; }
    if (relayOn) { Serial.println(F("ERR BUSY")); return; }
    pulseLengthMs = requested < MAX_PULSE_MS ? requested : MAX_PULSE_MS;
    pulseStartMs = now;
    writeRelay(true);
    Serial.print(F("OK PULSE "));
    Serial.println(pulseLengthMs);
  }
}

void setup() {
  writeRelay(false);               // before anything else: the relay is off at power-up and after every reset
  pinMode(RELAY_PIN, OUTPUT);
  writeRelay(false);
  pinMode(ESTOP_PIN, INPUT_PULLUP);
  pinMode(LED_PIN, OUTPUT);
  Serial.begin(115200);
  wdt_enable(WDTO_120MS);          // a hung loop resets the board, and a reset switches the relay off
}

void loop() {
  wdt_reset();
  tick();
  while (Serial.available() > 0) {
    char c = (char)Serial.read();
    if (c == '\r') continue;
    if (c == '\n') {
      line[lineLength] = '\0';
      if (lineTooLong) Serial.println(F("ERR BAD_ARG"));
      else if (lineLength > 0) handle(line);
      lineLength = 0;
      lineTooLong = false;
    } else if (lineLength < MAX_LINE) {
      line[lineLength++] = c;
    } else {
      lineTooLong = true;
    }
  }
}
