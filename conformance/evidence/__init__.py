"""Evidence: independent views of the bytes on the wire (scapy layer, captures)."""
