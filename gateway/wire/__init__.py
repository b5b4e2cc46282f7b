"""What inputs, outputs and the simulated PLC share on the wire: the Modbus register codec
(:mod:`.codec`), the read-only register server (:mod:`.registers`), the result-register map
(:mod:`.results`: block layout, verdict codes, overlap check) and OPC UA application
certificates (:mod:`.certs`)."""
